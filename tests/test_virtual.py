"""laboratory.virtual: overrides reach every laboratory's config (pydantic or dataclass), and
the module a Dask worker imports needs no pytest."""

from __future__ import annotations

import subprocess
import sys

import pytest

from laboratory.virtual import virtual_station


def test_overrides_reach_dataclass_params():
    st = virtual_station("cigtf", seed=3, overrides={"latitude_deg": 30.5})
    assert st.cfg.params.latitude_deg == 30.5 and st.seed == 3
    with pytest.raises(ValueError, match="no field 'nope' in CigtfParams"):
        virtual_station("cigtf", overrides={"nope": 1.0})
    isu = virtual_station("isu", overrides={"site.latitude_deg": -33.0})
    assert isu.cfg.site.latitude_deg == -33.0


def test_virtual_imports_no_pytest():
    code = "import sys, laboratory.virtual; print('pytest' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.strip()
    assert out == "False"
