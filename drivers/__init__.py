"""The wire: the abstract joint bus and the real device drivers.

Everything here talks to hardware (or to anything that speaks the same bytes) through
`dynamixel-sdk` and `python-can`/`canopen`. Device units exist only inside this package and are
converted in one place per quantity. This package never imports `sim_backend`.
"""
