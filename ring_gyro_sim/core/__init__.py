"""Model core: parameters, structure, electrostatic forces, kernels and the Simulator.

This layer imports only the standard library, numpy, scipy and numba (a test enforces it).
"""
