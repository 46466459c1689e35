"""Research checks run with the default suite (``testpaths`` in pyproject.toml): the studies' modules are plain
scripts, not a package, so their folders go on ``sys.path`` here (as running a script from its folder does)."""
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
for study in ("turn_sweeps", "buckling/check"):
    path = str(HERE / study)
    if path not in sys.path:
        sys.path.insert(0, path)
