"""One spacecraft definition for every tool: Python, TOML, a catalogue."""

from .library import list_spacecraft, load_spacecraft, spacecraft_toml
from .definition import Spacecraft, SpacecraftFileError, spacecraft_parts
from .toml_io import spacecraft_from_toml, spacecraft_to_toml

__all__ = [
    "Spacecraft",
    "SpacecraftFileError",
    "list_spacecraft",
    "load_spacecraft",
    "spacecraft_from_toml",
    "spacecraft_parts",
    "spacecraft_to_toml",
    "spacecraft_toml",
]
