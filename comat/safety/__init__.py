"""Control-barrier-function safety filter (OSQP), between every policy output and the wheels."""

from comat.safety.filter import InfeasibleError, SafetyFilter, SafetyInfo

__all__ = ["InfeasibleError", "SafetyFilter", "SafetyInfo"]
