"""Reading CONTACT's reference outputs (third-party, Apache-2.0) for the creep-model tests.

The files stay in ``../shared/reference/contact`` beside the repository with their
licence; the tests that need them are skipped when the folder is absent.
``BRAKETHERMO_REFERENCE`` overrides the location (e.g. a worktree elsewhere).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest

REFERENCE = Path(
    os.environ.get(
        "BRAKETHERMO_REFERENCE",
        Path(__file__).resolve().parents[1].parent / "shared" / "reference",
    )
)
CONTACT = REFERENCE / "contact"
needs_contact = pytest.mark.skipif(
    not (CONTACT / "tractcurv.ref_out").is_file(),
    reason=f"CONTACT reference outputs not present at {CONTACT}",
)


def contact_cases(name: str) -> np.ndarray:
    """Per case of a CONTACT ``.ref_out``: CKSI, CETA, CPHI (1/mm), FN, FX, FY (N)."""
    text = (CONTACT / name).read_text()
    rows = []
    for case in re.split(r"\n Case +\d+\n", text)[1:]:
        kin = re.search(r"CKSI\s+CETA\s+CPHI\n\s*(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)\s+(\S+)",
                        case)  # fmt: skip
        force = re.search(r"TOTAL FORCES.*\n.*\n\s*(\S+)\s+(\S+)\s+(\S+)", case)
        assert kin and force, f"unexpected CONTACT output layout in {name}"
        rows.append([float(kin.group(i)) for i in (4, 5, 6)]
                    + [float(force.group(i)) for i in (1, 2, 3)])  # fmt: skip
    return np.array(rows)


def contact_value(name: str, label: str, case: int = 1) -> list[float]:
    """The numbers on the line after ``label`` in case ``case`` (1-based) of an output."""
    text = (CONTACT / name).read_text()
    part = re.split(r"\n Case +\d+\n", text)[case]
    m = re.search(re.escape(label) + r".*\n(.*)\n", part)
    assert m, f"{label!r} not in case {case} of {name}"
    return [float(v) for v in m.group(1).split()]
