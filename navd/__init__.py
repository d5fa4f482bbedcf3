"""navd: the onboard navigation daemon for small AUVs (docs/architecture.md)."""
