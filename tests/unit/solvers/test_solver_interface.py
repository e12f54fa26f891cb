"""Every backend satisfies the solver protocol (solvers/interface.py); the factory (solvers/factory.py)
builds each choice; the block solvers share BlockOptions with their own defaults."""

from __future__ import annotations

import importlib.util
from dataclasses import fields

import numpy as np
import pytest
import scipy.sparse as sp

from polypore.core.errors import InputError
from polypore.solvers.block_contact import BlockContactSolver, BlockPoroSolver, ContactCondensation
from polypore.solvers.factory import BlockProblem, SolverChoice, build, coupled_solvers
from polypore.solvers.interface import BlockOptions, LinearSystemSolver
from polypore.solvers.linear import BLOCK_BACKENDS, LinearSolver

MEMBERS = ("backend", "takes_blocks", "takes_target", "krylov_iterations", "solve", "release",
           "set_pressure_nullspace")
PLAIN = ["superlu", "amg"] + (["pardiso"] if importlib.util.find_spec("pypardiso") else [])
HAVE_PETSC = importlib.util.find_spec("petsc4py") is not None


def _problem(coupled=False) -> BlockProblem:
    cond = ContactCondensation(np.ones(2), np.tile([0.0, 1.0], (2, 1)))
    return BlockProblem(8, 2, 4, cond, np.zeros((8, 3)), (np.ones(3, bool), np.zeros(3, bool)) if coupled else None,
                        coupled)


def _check(solver):
    assert isinstance(solver, LinearSystemSolver)
    for name in MEMBERS:
        assert hasattr(solver, name), name
    assert isinstance(solver.backend, str) and isinstance(solver.takes_blocks, bool)
    assert isinstance(solver.takes_target, bool) and list(solver.krylov_iterations) is not None


@pytest.mark.parametrize("backend", PLAIN)
def test_linear_solver_backends_satisfy_the_protocol(backend):
    s = LinearSolver(backend, symmetric=True)
    _check(s)
    assert s.backend == backend and not s.takes_blocks and not s.takes_target
    A = sp.diags([4.0, 5.0, 6.0]).tocsr()
    assert np.allclose(s.solve(A, np.ones(3)), 1 / np.array([4.0, 5.0, 6.0]))
    s.release()
    s.set_pressure_nullspace(np.ones(3))


@pytest.mark.parametrize("mechanics", ["amg", "direct"])
def test_block_solvers_satisfy_the_protocol(mechanics):
    c = BlockContactSolver(8, 2, _problem().condensation, mechanics=mechanics)
    p = BlockPoroSolver(8, 2, 4, _problem().condensation, mechanics=mechanics)
    for s in (c, p):
        _check(s)
        assert s.takes_blocks and s.takes_target
        assert s.backend == ("block-direct" if mechanics == "direct" else "block-amg")
        assert s.krylov_iterations is s.iterations
    p.set_pressure_nullspace(np.ones(3))
    assert np.array_equal(p.pressure_nullspace, np.ones(3))


@pytest.mark.skipif(not HAVE_PETSC, reason="petsc4py not installed")
def test_petsc_solvers_satisfy_the_protocol():
    from polypore.solvers.petsc import PetscLinearSolver
    from polypore.solvers.petsc_fieldsplit import PetscBlockContactSolver, PetscBlockPoroSolver

    cond = _problem().condensation
    for s in (PetscLinearSolver(), PetscBlockContactSolver(8, 2, cond), PetscBlockPoroSolver(8, 2, 4, cond)):
        _check(s)
        assert s.backend in ("petsc", "block-petsc") and not s.takes_blocks


def test_block_options_keep_each_solvers_defaults():
    """maxiter 300 (contact) / 400 (coupled), accept_rtol 1e-6 / 1e-4 (SciPy coupled), as before
    the options were shared."""
    cond = _problem().condensation
    c, p = BlockContactSolver(8, 2, cond), BlockPoroSolver(8, 2, 4, cond)
    assert isinstance(c, BlockOptions) and isinstance(p, BlockOptions)
    assert (c.rtol, c.maxiter, c.restart, c.accept_rtol, c.mechanics) == (1e-8, 300, 100, 1e-6, "amg")
    assert (p.rtol, p.maxiter, p.restart, p.accept_rtol, p.pressure) == (1e-8, 400, 100, 1e-4, "auto")
    shared = {f.name for f in fields(BlockOptions)}
    assert {"rtol", "maxiter", "restart", "accept_rtol", "mechanics", "amg", "options", "reuse"} <= shared


def test_factory_builds_each_choice():
    for backend in PLAIN:
        s = build(SolverChoice(backend))
        assert isinstance(s, LinearSolver) and s.backend == backend
    assert build(None).backend in ("pardiso", "superlu")
    ready = LinearSolver("superlu")
    assert build(ready) is ready
    # the block backends from the model's problem (called only for them); contact rtol rule
    c = build(SolverChoice("block-direct", rtol=1e-10), _problem)
    assert isinstance(c, BlockContactSolver) and c.mechanics == "direct" and c.rtol == 1e-10
    assert build(SolverChoice("block-amg", rtol=1e-6), _problem).rtol == 1e-8
    p = build(SolverChoice("block-amg"), lambda: _problem(coupled=True))
    assert isinstance(p, BlockPoroSolver) and p.rtol == 1e-8 and p.pressure_groups is not None
    with pytest.raises(InputError, match="^backend: 'block-amg' applies to contact mechanics"):
        build(SolverChoice("block-amg"))
    with pytest.raises(InputError, match="^backend: 'block-amg' is a block solver"):
        LinearSolver("block-amg")
    with pytest.raises(InputError, match="^backend: unknown linear solver 'lu'"):
        SolverChoice("lu")
    assert set(BLOCK_BACKENDS) == {"block-amg", "block-direct", "block-petsc"}


def test_coupled_solvers():
    """A plain choice: one solver for the steps, the initial equilibrium and the flow model; a
    block choice: the mechanics' block solver from the same choice, plain AMG for the flow model."""
    s = coupled_solvers(SolverChoice("superlu"))
    assert isinstance(s.coupled, LinearSolver) and s.coupled is s.mechanics is s.flow
    b = coupled_solvers(SolverChoice("block-amg"))
    assert b.coupled == b.mechanics == SolverChoice("block-amg")
    assert isinstance(b.flow, LinearSolver) and b.flow.backend == "amg" and b.flow.symmetric
    d = coupled_solvers(SolverChoice("block-direct"))
    assert isinstance(d.flow, LinearSolver) and d.flow.backend in ("pardiso", "superlu")


def test_the_case_file_names_the_solver_keys():
    from polypore.setup.solver import solver_choice

    with pytest.raises(InputError, match="^solver.linear: unknown linear solver"):
        solver_choice("lu")
