"""Export of Robotarium submissions and the numpy runtime shipped in them (see issue: Sim2Real)."""

import sys

from comat.models import comat_schema

# runtime.py imports the weight description by the flat name it has in an export folder, where
# both files are shipped side by side; in the repository that name is comat's module.
sys.modules["comat_schema"] = comat_schema

from sim2real.runtime import ComatRuntime, load_weights, save_weights
from sim2real.weights import comat_arrays, export_weights

__all__ = ["ComatRuntime", "comat_arrays", "export_weights", "load_weights", "save_weights"]
