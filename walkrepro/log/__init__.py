"""The log contract: a run's MCAP file written and read (:mod:`~walkrepro.log.record`),
the protobuf schemas of its numeric topics, the Foxglove frames and scene, the
MCAP writer underneath, a controller's signal vector and the run's provenance
metadata. Everything downstream reads a run through this package only.
"""
