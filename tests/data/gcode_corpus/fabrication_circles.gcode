(GCode fabricated on Tue, 27 Oct 2015 09:28:55 +0000 http://davro.net)
G90 (absolute mode)
F1000  (Feed Rate)
S0  (Spindle Speed)
G21 (Metric mm)
(circle)
G0 X20 Y50
G1 Z0 (axis spindle start point)
G17 G2 X20 Y50 I30 J0.00 Z0
G0 Z10 (axis spindle start position)
(/circle)

(circle)
G0 X90 Y50
G1 Z0 (axis spindle start point)
G17 G2 X90 Y50 I30 J0.00 Z0
G0 Z10 (axis spindle start position)
(/circle)

(circle)
G0 X160 Y50
G1 Z0 (axis spindle start point)
G17 G2 X160 Y50 I30 J0.00 Z0
G0 Z10 (axis spindle start position)
(/circle)

(circle)
G0 X230 Y50
G1 Z0 (axis spindle start point)
G17 G2 X230 Y50 I30 J0.00 Z0
G0 Z10 (axis spindle start position)
(/circle)

(circle)
G0 X20 Y120
G1 Z0 (axis spindle start point)
G17 G2 X20 Y120 I30 J0.00 Z0
G0 Z10 (axis spindle start position)
(/circle)

(circle)
G0 X90 Y120
G1 Z0 (axis spindle start point)
G17 G2 X90 Y120 I30 J0.00 Z0
G0 Z10 (axis spindle start position)
(/circle)

(circle)
G0 X160 Y120
G1 Z0 (axis spindle start point)
G17 G2 X160 Y120 I30 J0.00 Z0
G0 Z10 (axis spindle start position)
(/circle)

(circle)
G0 X230 Y120
G1 Z0 (axis spindle start point)
G17 G2 X230 Y120 I30 J0.00 Z0
G0 Z10 (axis spindle start position)
(/circle)

M2
