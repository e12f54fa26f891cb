"""polypore: poromechanics of fractured rock with frictional contact on polytopal meshes.

Layers (a lower layer never imports a higher one; ``tests/structure/test_layers.py`` checks it)::

    core -> mesh -> discretisation -> assembly -> solvers -> models -> io -> cases -> setup -> runs -> cli

``cases`` holds the built-in case files and their exact solutions, ``setup`` turns a case file
into model objects, ``runs`` holds the run drivers.
"""

__version__ = "0.1.0"
