"""The bench: the world simulator, device emulators on pseudo-terminals, and the runner."""
