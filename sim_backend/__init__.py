"""The emulated hardware: a MuJoCo plant of the testbed behind byte-exact bus emulators.

A Dynamixel Pro H54-200-S500-R chain answers Protocol 2.0 on a pseudo-terminal; CiA 406 link
encoders answer SYNC on CAN. This package never imports `drivers`: the two meet on the wire.
"""
