"""Multi-target vehicle tracking on the shared estimation core."""
