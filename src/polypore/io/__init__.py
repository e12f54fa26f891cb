"""Output layer: VTU/PVD, JSON and CSV files, written atomically."""
