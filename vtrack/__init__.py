"""vtrack: vehicle tracking in traffic video on one shared estimation core."""

__version__ = "0.1.0"
