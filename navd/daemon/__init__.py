"""The daemon: device tasks, the tick, health, zenoh and the log, around the filter."""
