(vmt: one 60 mm slot along +X at 15000 rpm, 0.1 mm per tooth on two teeth: F3000)
G21 G90 G17
G0 X150 Y200 Z200
M3 S15000
G1 X210 F3000
M5
G0 Z250
M30
