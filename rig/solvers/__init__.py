"""ODE solver objects (step(), dense output, events, statistics) and an event-locating driver, independent of
problems: explicit Euler, symplectic Euler, RK4, DP45, Tsit5, DOP853, Rodas4 (each compiled for a numba right-hand side),
Rosenbrock23, closed-form segments. Reference: docs/solvers.md."""
from rig.solvers.base import OdeSolver, ResolutionWarning, SolverDivergence, StiffnessError, StiffnessWarning
from rig.solvers.compiled import JitRhs
from rig.solvers.dop853 import DOP853
from rig.solvers.dopri import DormandPrince45
from rig.solvers.euler import Euler, SymplecticEuler
from rig.solvers.flow import AffineRotor, ClosedForm, ClosedFormSolver
from rig.solvers.implicit import Rosenbrock23
from rig.solvers.integrate import METHODS, Event, EventRecord, Problem, Solution, integrate
from rig.solvers.rk4 import RK4
from rig.solvers.rodas import Rodas4
from rig.solvers.tsit5 import Tsitouras45

__all__ = ["DOP853", "METHODS", "RK4", "AffineRotor", "ClosedForm", "ClosedFormSolver", "DormandPrince45", "Euler", "Event",
           "EventRecord", "JitRhs", "OdeSolver", "Problem", "Rodas4", "Rosenbrock23", "Solution", "SolverDivergence",
           "ResolutionWarning", "StiffnessError", "StiffnessWarning", "SymplecticEuler", "Tsitouras45", "integrate"]
