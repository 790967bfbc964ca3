"""Paper I (Lee et al.) figures on small synthetic logs."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from test_metrics import DT, Tick, make_spec, write_log  # noqa: E402

from walkrepro.papers.lee2021 import figures  # noqa: E402


def test_switch_marks_include_ssd_straight_to_ds(tmp_path: Path) -> None:
    """An SSD that ends in SSA and DS within one tick (logged 0 → 2) is marked, not a crash."""
    phases = [2.0] * 5 + [0.0] * 5 + [2.0] * 5
    ticks = [Tick(round(k * DT, 6), signals={"efsm_phase": p}) for k, p in enumerate(phases)]
    spec = make_spec(controller={"type": "efsm", "params": {}})
    d = write_log(tmp_path / "s.mcap", ticks, spec)
    fig, ax = plt.subplots()
    figures._switches(ax, d, 1.0)
    assert len(ax.lines) == 2
    plt.close(fig)
