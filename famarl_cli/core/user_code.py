"""Users' own modules, named ``module:attribute`` (an expert, an env), are found in the current folder too, as
``python -m`` and ``python script.py`` find them: an installed command such as ``famarl`` starts without the current
folder on ``sys.path``."""

from __future__ import annotations

import os
import sys


def importable_from_here() -> None:
    """Add the current folder to the end of ``sys.path`` (once): a module of the user's folder imports, and one
    that shares a name with an installed package does not shadow it."""
    here = os.getcwd()
    if here not in sys.path and "" not in sys.path:
        sys.path.append(here)
