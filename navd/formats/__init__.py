"""File formats: JSON Lines, the measurement log, the daemon's record log, the output schema."""
