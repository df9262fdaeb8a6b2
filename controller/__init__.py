"""The math of Kim et al., ICRA 2018, for n flexible joints: pure numpy/scipy, no I/O.

One module per block of the paper: model (1)-(4), (20); LQR (21)-(24); DOB (9)-(11);
gravity compensator (5)-(8); composition (25); baselines. Imports nothing of ours.
"""
