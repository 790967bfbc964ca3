"""The process around a run: stop signals (Ctrl-C, SIGTERM) as a request, numba's
source-keyed cache, the GL backend for rendering. The command sets them up when it
starts (``cli.command_setup``); the library on first use, leaving the environment as
it was.
"""
