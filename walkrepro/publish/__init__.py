"""The reproduction as documents: the static HTML report, the documentation generated
from the code and the results, the provenance ledger of every number a run uses.
"""
