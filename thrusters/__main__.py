"""``python -m thrusters``: seed 004 Tables 3 and 5 beside ours."""

from .simulation import main

main()
