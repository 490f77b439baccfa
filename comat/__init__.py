"""comat: a MuJoCo Sim2Real testbed for heterogeneous robot teams on the Robotarium, and COMAT.

Subpackages: :mod:`comat.mjcf` (MJCF generation), :mod:`comat.sim` (MuJoCo worlds),
:mod:`comat.safety` (barrier filter), :mod:`comat.control` (the per-tick pipeline). Importing
``comat`` itself is light: no torch, no rerun.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
