"""Memory-lean assembly: int32 index arrays (core/memory.py) and the block-sparse interleave
of the elastic matrix (assembly/elasticity.py), equal to what they replace."""
import numpy as np
import scipy.sparse as sp


def test_int32_indices_in_place_when_they_fit():
    """core/memory.py::int32_indices: int64 index arrays of a csr become int32, same matrix."""
    from polypore.core.memory import int32_indices

    rng = np.random.default_rng(1)
    r, c = rng.integers(0, 50, 300).astype(np.int64), rng.integers(0, 40, 300).astype(np.int64)
    A = sp.coo_array((rng.standard_normal(300), (r, c)), shape=(50, 40)).tocsr()
    A.indices, A.indptr = A.indices.astype(np.int64), A.indptr.astype(np.int64)
    ref = A.toarray()
    assert int32_indices(A) is A
    assert A.indices.dtype == np.int32 and A.indptr.dtype == np.int32
    assert np.array_equal(A.toarray(), ref)


def test_interleave_is_the_coordinate_assembly_entry_for_entry():
    """assembly/elasticity.py::interleave (block-sparse on the union pattern, zeros dropped) gives
    the coordinate assembly of the d × d blocks: same pattern, same values; blocks with different
    patterns and a missing block included."""
    from polypore.assembly.elasticity import interleave

    rng = np.random.default_rng(7)
    n, d = 40, 3
    blocks = [[sp.random_array((n, n), density=0.1, random_state=rng, format="csr") for _ in range(d)]
              for _ in range(d)]
    blocks[0][2] = None
    rows, cols, vals = [], [], []
    for i in range(d):
        for j in range(d):
            if blocks[i][j] is not None:
                B = blocks[i][j].tocoo()
                rows.append(B.row * d + i)
                cols.append(B.col * d + j)
                vals.append(B.data)
    ref = sp.coo_array((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n * d, n * d)).tocsr()
    A = interleave(blocks, d)
    assert A.nnz == ref.nnz
    assert np.array_equal(A.indptr, ref.indptr) and np.array_equal(A.indices, ref.indices)
    assert np.array_equal(A.data, ref.data)


def test_csr_positions_find_stored_entries_and_only_those():
    """core/csr.py: positions of (row, col) in M.data where M stores them, found False elsewhere."""
    from polypore.core.csr import csr_positions

    rng = np.random.default_rng(9)
    M = sp.random_array((30, 20), density=0.2, random_state=rng, format="csr")
    M.sort_indices()
    r, c = rng.integers(0, 30, 500), rng.integers(0, 20, 500)
    pos, found = csr_positions(M, r, c)
    dense = M.toarray()
    stored = np.zeros((30, 20), bool)
    coo = M.tocoo()
    stored[coo.row, coo.col] = True
    assert np.array_equal(found, stored[r, c])
    assert np.array_equal(M.data[pos[found]], dense[r[found], c[found]])
