"""Readable numpy references of walkrepro's compiled algorithms, kept as test oracles only: the
package runs the compiled kernels, and the tests check them against these."""
