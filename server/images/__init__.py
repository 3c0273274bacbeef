"""The images the rover sent, served to the ground: their routes (``api``) and answer
models (``answers``); stored by ``server.storage.images``."""
