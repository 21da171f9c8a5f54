G1 F[150 * 60]
X0  Y100  (up)
X20 Y100  (short right)
Y30       (down to the knee)
G3 X30 Y20 I10 J0  (rounded knee)
X100      (right to end of bracket)
Y0        (to the bottom)
X0 Y0     (and back to origin)
