"""polypore: poromechanics of fractured rock with frictional contact on polytopal meshes.

Layers (a lower layer never imports a higher one; ``tests/test_layers.py`` checks it)::

    core -> mesh -> discretisation -> assembly -> solvers -> models -> io -> cases -> cli
"""

__version__ = "0.1.0"
