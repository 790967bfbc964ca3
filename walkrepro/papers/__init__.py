"""walkrepro's own papers, each declared as a plugin exactly as an outside package would be
(``walkrepro.plugins``; the entry points are in walkrepro's ``pyproject.toml``).

One package per paper (``lee2021``, ``faraji``, ``jo_oh``): its controller and the modules
it is built from, its metrics (``metrics.py``) and its figures (``figures.py``); the package's
``PLUGIN`` declares them. The core (everything outside ``walkrepro/papers/``) never imports a
paper: it reaches them through the plugin registry only.
"""
