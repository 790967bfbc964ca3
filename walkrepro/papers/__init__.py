"""walkrepro's own papers, each declared as a plugin exactly as an outside package would be
(``walkrepro.plugins``; the entry points are in walkrepro's ``pyproject.toml``).

One module per paper: its controller, its metric module and its figure module.
"""
