"""ODE solver objects (step(), dense output, status) and an event-locating driver, independent of problems."""
from rig.solvers.base import OdeSolver, SolverDivergence, StiffnessError, StiffnessWarning
from rig.solvers.dopri import DormandPrince45
from rig.solvers.flow import AffineRotor, ClosedForm, ClosedFormSolver
from rig.solvers.implicit import Rosenbrock23
from rig.solvers.integrate import METHODS, Event, EventRecord, Problem, Solution, integrate
from rig.solvers.rk4 import RK4

__all__ = ["METHODS", "RK4", "AffineRotor", "ClosedForm", "ClosedFormSolver", "DormandPrince45", "Event",
           "EventRecord", "OdeSolver", "Problem", "Rosenbrock23", "Solution", "SolverDivergence", "StiffnessError",
           "StiffnessWarning", "integrate"]
