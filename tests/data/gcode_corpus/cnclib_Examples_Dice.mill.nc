(.../pcb-gcode-3.6.2.4/pcb-gcode.ulp)
(Copyright 2005 - 2012 by John Johnson)
(See readme.txt for licensing terms.)
(This file generated from the board:)
(.../projects/DiceCR2302/DiceCR2302.brd)
(Current profile is .../pcb-gcode-3.6.2.4/profiles/mach.pp  )
(This file generated 21.12.2017 23:48)
(Settings from pcb-machine.h)
(spindle on time = 1.0000)
(spindle speed = 30000.0000)
(milling depth = -2.0000)
(tool change at 0.0000  0.0000  10.0000 )
(feed rate xy = F100   )
(feed rate z  = F99    )
(Z Axis Settings)
(  High     Up        Down     Drill)
(12.7000 	0.5000  	-0.1500 	-2.0000 )
(Settings from pcb-defaults.h)
(isolate min = 0.0000)
(isolate max = 0.1500)
(isolate step = 0.1500)
(Generated bottom outlines, bottom drill, )
(Unit of measure: mm)
(Metric Mode)
G21
(Absolute Coordinates)
G90
S30000
G00 Z12.7000 
G00 X0.0000  Y0.0000  
M03
G04 P1.000000
G00 Z0.5000  
G00 X0.6350  Y-0.6350 
G01 Z-2.0000 F99    
G01 X0.6350  Y33.6550 F300   
G01 X-69.8500 Y33.6550 
G01 X-69.8500 Y-0.6350 
G01 X0.6350  Y-0.6350 
G00 Z12.7000 
M05
M02
