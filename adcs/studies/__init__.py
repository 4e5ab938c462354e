"""Design studies of `adcs report`, one module each with ``run(ctx)``."""
