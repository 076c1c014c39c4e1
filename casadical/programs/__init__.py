"""Robot programs: read, filter with a calibration, write back (URScript, KUKA KRL, ABB RAPID).

:mod:`.program` holds what every language shares (the targets, their numbers in the text, the controllers'
orientation conventions, number formatting); one module per language reads a program into it
(:mod:`.urscript`, :mod:`.krl`, :mod:`.rapid`) and writes a measurement run as a program; :mod:`.filter`
corrects a program's targets with a calibration (``casadical compensate CAL.json PROGRAM --out FILTERED``).
Nothing is imported here: importing one module imports no other.
"""
