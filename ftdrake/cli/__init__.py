"""The `ftdrake` command line: thin parse → call → print."""

from .main import main

__all__ = ["main"]
