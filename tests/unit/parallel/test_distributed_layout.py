"""The serial pieces of distributed runs (docs/parallel.md): the cell graph METIS partitions, the owners
of the unknowns, and the dof layout's renumbering. No MPI needed: a stand-in communicator gives the
rank; the 2-rank runs themselves are in test_petsc_mpi.py."""

import numpy as np
import pytest
import scipy.sparse as sp

from polypore.parallel.partition import cell_graph, partition_cells
from polypore.setup.casefile import load_case
from polypore.setup.meshing import build_fractured_mesh
from polypore.setup.poromechanics import poro_setup
from polypore.parallel.layout import DofLayout, min_owner


class FakeComm:
    def __init__(self, rank, size):
        self.rank, self.size = rank, size

    def Get_rank(self):
        return self.rank

    def Get_size(self):
        return self.size


def _c4():
    case = load_case("dfm-2d", ["mesh.size=0.2", "mesh.fracture_size=0.1"])
    fm = build_fractured_mesh(case)
    return fm, poro_setup(case, fm)[0]


def test_cell_graph_links_the_two_cells_of_every_interior_face():
    fm, _ = _c4()
    mesh = fm.mesh
    xadj, adj = cell_graph(mesh)
    rows = np.repeat(np.arange(mesh.n_cells), np.diff(xadj))
    G = sp.csr_matrix((np.ones(adj.size), (rows, adj)), shape=(mesh.n_cells,) * 2)
    assert (G != G.T).nnz == 0 and G.diagonal().sum() == 0
    K, L = mesh.face_cells.T
    inner = L >= 0
    assert adj.size == 2 * inner.sum()
    assert np.all(G[K[inner], L[inner]] > 0)
    assert np.all(partition_cells(mesh, 1) == 0)


def test_owners_follow_the_cells_and_fracture_faces_have_one_rank():
    fm, model = _c4()
    mesh, net = fm.mesh, fm.network
    part = (mesh.geometry.cell_centroid[:, 0] > 0.5).astype(np.int64)      # two halves
    own = model.dof_owner(part)
    assert own.shape == (model.n_unknowns,) and set(np.unique(own)) == {0, 1}
    mech = model.mech
    # a slot: the lowest rank among the cells holding it
    cs = mech.space.cell_slots
    low = min_owner(mech.space.n_slots, cs.values, part[cs.rows_of_entries()])
    assert np.array_equal(mech.slot_owner(part), low)
    nfree, d = mech.free.size, mech.dim
    # a fracture face's multipliers: its + side cell's rank, both components together
    lam = own[nfree:nfree + net.n_faces * d].reshape(-1, d)
    assert np.array_equal(lam, np.repeat(part[net.plus_cell][:, None], d, axis=1))
    # one part: everything on rank 0
    assert np.all(model.dof_owner(np.zeros(mesh.n_cells, np.int64)) == 0)


def test_layout_makes_each_ranks_unknowns_contiguous_in_serial_order():
    rng = np.random.default_rng(3)
    n = 40
    owner = rng.integers(0, 3, n)
    A = sp.random(n, n, density=0.2, random_state=4, format="csr") + sp.identity(n, format="csr")
    Pm = sp.csr_matrix((np.ones(n), (np.arange(n), np.argsort(owner, kind="stable"))), shape=(n, n))
    PAPt = (Pm @ A @ Pm.T).tocsr()
    blocks = []
    for r in range(3):
        lay = DofLayout(owner, FakeComm(r, 3))
        assert np.all(owner[lay.owned] == r) and np.all(np.diff(lay.owned) > 0)      # serial order kept
        assert lay.n_local == np.sum(owner == r)
        R = lay.rows(A)
        assert abs(R - PAPt[lay.start:lay.end]).max() == 0
        b = np.arange(n, dtype=float)
        assert np.array_equal(lay.local(b), b[lay.owned])
        f = lay.field(np.arange(10, 20))
        assert np.all((f >= lay.start) & (f < lay.end)) and np.all(np.diff(f) > 0)
        assert set(lay.field_rows(np.arange(10, 20))) == {i for i in range(10, 20) if owner[i] == r}
        blocks.append(lay.owned)
    assert np.array_equal(np.concatenate(blocks), np.argsort(owner, kind="stable"))
    one = DofLayout.contiguous(n, FakeComm(0, 1))
    assert np.array_equal(one.owned, np.arange(n))


def test_block_pattern_restricted_to_a_ranks_rows_is_those_rows_of_the_whole_pattern():
    """Each rank's pattern (its rows, distributed columns) filled with its blocks' kept values gives
    exactly, bit for bit, its rows of the whole filled matrix: duplicates are summed in the same
    order (what the models' owned-row assembly relies on)."""
    from polypore.assembly.pattern import BlockPattern

    rng = np.random.default_rng(7)
    n = 37
    blocks = [(rng.integers(0, n, 200), rng.integers(0, n, 200)),          # duplicates on purpose
              (rng.integers(0, n, (15, 3, 3)), rng.integers(0, n, (15, 3, 3))),
              (np.arange(n), np.arange(n))]
    values = [rng.standard_normal(200), rng.standard_normal((15, 3, 3)), rng.standard_normal(n)]
    whole = BlockPattern.build(blocks, (n, n))
    full = whole.fill([whole.take(k, v) for k, v in enumerate(values)])
    owner = rng.integers(0, 3, n)
    total = 0
    for r in range(3):
        lay = DofLayout(owner, FakeComm(r, 3))
        part = BlockPattern.build(blocks, (n, n), row_local=lay.local_index, col_map=lay.inv, n_rows=lay.n_local)
        R = part.fill([part.take(k, v) for k, v in enumerate(values)])
        ref = lay.rows(full)
        assert R.shape == ref.shape == (lay.n_local, n)
        assert np.array_equal(R.indptr, ref.indptr) and np.array_equal(R.indices, ref.indices)
        assert np.array_equal(R.data, ref.data)
        total += R.nnz
    assert total == full.nnz
    assert all(k is None for k in whole.keep)                  # unrestricted: no index lists
    # block by block (a fixed block summed once, the others added per iteration) in block order:
    # the same sums as fill, bit for bit, also on a rank's rows
    data = whole.add(whole.add(whole.zeros(), 0, values[0]), 1, values[1])
    assert np.array_equal(whole.matrix(whole.add(data, 2, values[2])).data, full.data)
    with pytest.raises(ValueError, match="block 1"):
        whole.add(whole.zeros(), 1, values[0])
    R = part.matrix(part.add(part.add(part.add(part.zeros(), 0, part.take(0, values[0])), 1, part.take(1, values[1])),
                             2, part.take(2, values[2])))
    assert np.array_equal(R.data, part.fill([part.take(k, v) for k, v in enumerate(values)]).data)


def test_run_summary_has_the_time_split(tmp_path, cli):
    """summary.json's totals: assembly, preconditioner set-up, Krylov and the rest add up to the run's
    seconds (wall and CPU), the linear solves contain set-up and Krylov; `polypore run` prints it."""
    out = tmp_path / "c5"
    code, text, err = cli("run", "dfm-3d", "--out", str(out), "--set", "mesh.size=0.25", "--set", "time.end=2",
                          "--set", "time.output_times=[2.0]", "--set", "solver.linear=block-amg")
    assert code == 0, err
    import json

    t = json.loads((out / "summary.json").read_text())["totals"]
    for clock in (t, t["cpu"]):
        parts = [clock[f"seconds_{k}"] for k in ("assembly", "preconditioner", "krylov", "other")]
        assert all(p >= 0 for p in parts[:3]) and clock["seconds_krylov"] > 0 and clock["seconds_assembly"] > 0
        assert abs(sum(parts) - clock["seconds"]) <= 1e-9 * clock["seconds"]
        assert clock["seconds_preconditioner"] + clock["seconds_krylov"] <= clock["seconds_linear"] + 1e-9
    assert "ranks" not in t and t["peak_memory_mb"] > 0
    line = [ln for ln in text.splitlines() if ln.strip().startswith("time:")]
    assert len(line) == 1 and "preconditioner set-up" in line[0] and "Krylov" in line[0]


def test_time_line_names_the_parts_of_a_direct_solve(tmp_path, cli):
    """Issue 25: a SuperLU run's time line said "preconditioner set-up" and "Krylov". The line
    and summary.json now name what ran: the factorisation and the triangular solves."""
    import json

    from conftest import STATIC_2D
    from polypore.core.timing import split_labels

    case = tmp_path / "s.toml"
    case.write_text(STATIC_2D)
    out = tmp_path / "o"
    code, text, err = cli("run", str(case), "--out", str(out), "--set", "solver.linear=superlu")
    assert code == 0, err
    line = [ln for ln in text.splitlines() if ln.strip().startswith("time:")]
    assert len(line) == 1 and "factorisation" in line[0] and "triangular solves" in line[0], line
    assert "preconditioner" not in line[0] and "Krylov" not in line[0]
    t = json.loads((out / "summary.json").read_text())["totals"]
    assert t["linear_solver"] == "superlu" and t["labels"]["preconditioner"] == "factorisation"
    # PARDISO factorises and solves in one call: one part, no empty "solve" column
    assert split_labels("pardiso") == {"assembly": "assembly", "preconditioner": "factorisation and solve",
                                       "other": "other"}
    assert split_labels("block-amg")["krylov"] == "Krylov iterations"


def test_block_pattern_put_scatters_a_block_of_distinct_entries_as_add_does():
    """put (a plain scatter) on a block whose entries have distinct slots gives add's sums bit for
    bit, also when later blocks add into the same slots; distinct() tells such blocks apart."""
    from polypore.assembly.pattern import BlockPattern

    rng = np.random.default_rng(3)
    n = 29
    A = sp.random(n, n, density=0.2, random_state=4, format="coo")       # distinct (row, col)
    blocks = [(A.row, A.col), (rng.integers(0, n, 150), rng.integers(0, n, 150))]
    values = [A.data, rng.standard_normal(150)]
    pat = BlockPattern.build(blocks, (n, n))
    assert pat.distinct(0) and not pat.distinct(1)
    ref = pat.add(pat.add(pat.zeros(), 0, values[0]), 1, values[1])
    got = pat.add(pat.put(pat.zeros(), 0, values[0]), 1, values[1])
    assert np.array_equal(got, ref)
    with pytest.raises(ValueError, match="block 0"):
        pat.put(pat.zeros(), 0, values[1])


def test_cell_ownership_owned_and_ghost_cells():
    """A partition's owned cells and their one-face ghost layer; serially every cell is owned."""
    from polypore.mesh.generators.cartesian import cartesian_mesh
    from polypore.parallel.ownership import CellOwnership, cell_ownership

    mesh = cartesian_mesh([np.linspace(0, 4, 5), np.linspace(0, 1, 2)])      # a row of 4 cells
    x = mesh.geometry.cell_centroid[:, 0]
    own = CellOwnership.of(mesh, (x > 2).astype(int), rank=1, size=2)
    assert np.allclose(sorted(x[own.owned]), [2.5, 3.5]) and np.allclose(x[own.ghost], [1.5])
    s = cell_ownership(mesh)
    assert s.size == 1 and s.owned.all() and not s.ghost.any()
    with pytest.raises(ValueError, match="4 cells"):
        CellOwnership.of(mesh, np.zeros(3, int), 0, 1)
