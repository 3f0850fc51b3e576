"""Compiled Tsitouras 5(4) step (inserted into :mod:`runs` copies; same tableau, error norm and
controller as :class:`rig.solvers.tsit5.Tsitouras45`'s Python step)."""
from rig.solvers.dopri import EXPONENT, MAX_FACTOR, MIN_FACTOR, SAFETY  # the same controller; for erk
from rig.solvers.tsit5 import P, A, B, C, E  # A, B, C: for erk

# <include pair45>
