"""One sans-I/O codec per device, and the serial transport they share."""
