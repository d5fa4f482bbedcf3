"""Device emulators: each behaves as the device does on its serial line (written from the
protocol documents, not from navd's drivers), serving a real pseudo-terminal."""
