"""Distributed runs, below the discretisation: the communicator context, the partition of the
mesh's cells (METIS) and the layout of unknowns over ranks (owned rows, ghost columns).

`context` holds the communicator context (`activate`, `context`: COMM_WORLD, this rank, the
cell partitions, rank 0's broadcasts); `layout` :class:`~.layout.DofLayout` and the row-block
operators the models apply on their own rows; `ownership` the owned and ghost cells of a rank;
`partition` the cell graph and its partition. Serial runs never enter here beyond ``context()``
returning None (docs/parallel.md).
"""
