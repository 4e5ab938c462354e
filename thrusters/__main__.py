"""``python -m thrusters``: seed 004 Tables 3 and 5 beside ours."""

from .scenarios import main

main()
