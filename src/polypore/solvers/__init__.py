"""Solvers: the linear-solver interface and the semi-smooth Newton loop (no physics here).

Repeatability: MKL PARDISO's threaded factorisation adds in an order that changes from run to
run, and semi-smooth Newton turns those last-digit differences into different active-set
histories (different Newton iteration counts in identical runs). MKL's conditional numerical
reproducibility (CNR) fixes that order; MKL reads
``MKL_CBWR`` once, when it is first used, so it is set here, before any module of this package
loads pypardiso. A value set by the user is kept (docs/poromechanics.md, "Repeatable runs").
"""

import os

os.environ.setdefault("MKL_CBWR", "AUTO")
