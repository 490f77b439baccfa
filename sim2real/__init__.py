"""Export of Robotarium submissions and the numpy runtime shipped in them (see issue: Sim2Real)."""

from sim2real.runtime import ComatRuntime, load_weights, save_weights
from sim2real.weights import comat_arrays, export_weights

__all__ = ["ComatRuntime", "comat_arrays", "export_weights", "load_weights", "save_weights"]
