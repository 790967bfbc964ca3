"""Parameter sweeps: a grid of spec overrides, run cell by cell, reduced to a table and maps.

The flow mirrors a single run's, one level up::

    --grid FIELD=VALUES  → grid.py (axes, cells, each cell's resolved spec; all validated first)
                         → engines.py (process pool or Ray: only schedule)
                         → cells.py (one cell = one run, reduced to its metrics; a pure function
                           of the cell's resolved spec)
                         → store.py (sweep.yaml, cells.csv appended as cells finish, resume)
                         → maps.py (line plot / heat map / panels) and claims.py (paper claims
                           about regions of the map, as check rows)

This package's ``__init__`` imports nothing, so ``walkrepro.specs.models`` can import the spec models
(``walkrepro.specs.sweeps``) without pulling in the engines.
"""
