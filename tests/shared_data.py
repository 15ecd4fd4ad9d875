"""Where the tests find c't-Sim's own files (world files and IR characteristics, GPL-2, never copied
into the project): the folder `CTSIM_SHARED` names, else `../shared` beside the repository, the
same lookup as `bots.ir_curve.shared_folder`. Tests that need them skip, saying where they
looked and how to point them elsewhere."""

from __future__ import annotations

import pytest

from bots.ir_curve import shared_folder

SHARED = shared_folder()
PARCOURS = SHARED / "ctsim" / "parcours"
CURVES = SHARED / "ctsim" / "characteristics"

_HOW = "set CTSIM_SHARED to the folder holding ctsim/"
needs_parcours = pytest.mark.skipif(not PARCOURS.is_dir(), reason=f"c't-Sim's world files not found at {PARCOURS} ({_HOW})")
needs_curves = pytest.mark.skipif(not CURVES.is_dir(), reason=f"c't-Sim's IR characteristic files not found at {CURVES} ({_HOW})")
