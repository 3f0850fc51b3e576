"""Compiled Dormand–Prince 5(4) step (inserted into :mod:`runs` copies; same tableau, error norm and
controller as :class:`rig.solvers.dopri.DormandPrince45`'s Python step)."""
from rig.solvers.dopri import P, A, B, C, E, EXPONENT, MAX_FACTOR, MIN_FACTOR, SAFETY  # A…SAFETY: for pair45

# <include pair45>
