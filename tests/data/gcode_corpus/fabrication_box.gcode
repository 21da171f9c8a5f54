(GCode fabricated on Tue, 27 Oct 2015 09:29:06 +0000 http://davro.net)
G90 (absolute mode)
F2000  (Feed Rate)
S0  (Spindle Speed)
G21 (Metric mm)
(box)
G0 X10 Y10 Z10 (move to spindle axis start position)
G1 Z0
G1 X10 Y10 Z0
G1 Y50
G1 X50
G1 Y10
G1 X10
G0 Z0
(/box)

M2
