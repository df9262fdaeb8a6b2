"""pyserial URL handlers (`serial.serial_for_url("readahead:///dev/ttyACM0")`): see
`protocol_readahead`. Registered by `drivers.canbus.read_ahead.register()`."""
