g21
g90
; move to start position
g1x50y50f1800
z20f120
f1800
g91
; run
x100
y100
x-100
y-90
x90
y80
x-80
y-70
x70
y60
x-60
y-50
x50
y40
x-40
y-30
x30
y20
x-20
y-10
x10
y5
x-5
y-2.5
x2.5
; homing
g28

