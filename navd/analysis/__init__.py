"""After the mission: replay, report, calibration."""
