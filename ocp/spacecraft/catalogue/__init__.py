"""Built-in spacecraft: TOML files read by `load_spacecraft`."""
