"""The simulated robot and its world, in MuJoCo: the robot (MuJoCo and Pinocchio
models), the scene (floor, obstacles, contact, options), the contact models and the
contact readout, the sensors a controller sees, the disturbances, and replaying a
log's inputs through its own scene (``walkrepro verify``).
"""
