"""Assembly layer: global sparse matrices from the discretisation's operators."""
