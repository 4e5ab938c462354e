"""`ocp`: spacecraft models, slews, MPC, code export and the command line."""

__all__: list[str] = []
