"""``python -m walkrepro`` is the same as the ``walkrepro`` command."""

from walkrepro.cli import app

app()
