"""Optional dependencies: a missing extra is one line naming it (the core imports without them)."""
import subprocess
import sys

import pytest

from dnarod.core.extras import MissingExtraError, require


def test_missing_extra_names_it():
    with pytest.raises(MissingExtraError, match=r"pip install 'dnarod\[ensemble\]'"):
        require("dnarod_no_such_module_xyz", "ensemble")
    assert require("json", "ensemble").dumps([1]) == "[1]"


def test_the_core_and_the_cli_import_without_dask_or_pyarrow():
    """``dnarod simulate`` needs neither dask nor pyarrow: with both made unimportable the core API and the command
    line still load, and an ensemble's table asks for the extra in one line."""
    code = ("import sys; sys.modules['distributed'] = None; sys.modules['dask'] = None; sys.modules['pyarrow'] = None\n"
            "import dnarod, dnarod.run, dnarod.cli.main, dnarod.engines.openmm.simulation, dnarod.structure\n"
            "from dnarod.workflows.ensemble.results import rows_to_table\n"
            "try:\n    rows_to_table([{'a': 1}], ['a'])\nexcept Exception as e:\n    print(type(e).__name__, e)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert "MissingExtraError" in r.stdout and "dnarod[ensemble]" in r.stdout
