"""Built-in cases: case files (TOML) shipped with the package, and the layer that turns them into runs."""
