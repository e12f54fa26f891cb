"""Distributed runs, below the discretisation: the communicator context, the partition of the
mesh's cells (METIS) and the layout of unknowns over ranks (owned rows, ghost columns).

`layout` holds the context (`activate`, `context`), :class:`~.layout.DofLayout` and the
row-block operators the models apply on their own rows; `partition` the cell graph and its
partition. Serial runs never enter here beyond ``context()`` returning None (docs/parallel.md).
"""
