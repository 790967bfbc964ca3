"""Many runs: parameter sweeps and their maps, declared calibration, speed
measurement (``walkrepro bench``).
"""
