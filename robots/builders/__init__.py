"""The robots' MJCF builders (``robots/build_models.py`` runs them): a shared core and one
module per robot."""
