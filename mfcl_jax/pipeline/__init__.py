"""Real-data experiment runner (``experiments.real``) and occupancy maps from logs."""
