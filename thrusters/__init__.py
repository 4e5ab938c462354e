"""`thrusters`: six-thruster unit, duty-cycle laws and allocator."""

__all__: list[str] = []
