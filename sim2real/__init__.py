"""Export of Robotarium submissions and the numpy runtime shipped in them (see issue: Sim2Real)."""

__all__: list[str] = []
