"""Bottom layer: errors, ragged arrays and other dependency-free helpers."""
