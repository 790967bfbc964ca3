"""walkrepro.runtime.records: a StructRef record declared by name, read in Python and in
compiled code, and found again by numba's on-disk cache in a new process."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from walkrepro.runtime.records import define_record

PairType, Pair = define_record("Pair", ("a", "b"), __name__)


def test_members_are_read_and_written_by_name_in_python_and_compiled_code():
    import numba

    @numba.njit
    def bump(record):
        record.a[0] += record.b
        return record.a.sum()

    record = Pair(np.zeros(3), 2.5)
    assert bump(record) == 2.5
    assert record.b == 2.5
    np.testing.assert_array_equal(record.a, [2.5, 0.0, 0.0])


@pytest.mark.parametrize(
    ("name", "fields"), [("bad name", ("a",)), ("Rec", ()), ("Rec", ("a", "a")), ("Rec", ("1x",))]
)
def test_a_bad_declaration_is_refused(name, fields):
    with pytest.raises(ValueError, match="record"):
        define_record(name, fields, __name__)


def test_a_new_process_loads_the_compiled_function_from_the_cache(tmp_path):
    (tmp_path / "recmod.py").write_text(
        textwrap.dedent(
            """
            import numba
            from walkrepro.runtime.records import define_record
            PairType, Pair = define_record("Pair", ("a", "b"), __name__)

            @numba.njit(cache=True)
            def total(record):
                return record.a.sum() + record.b
            """
        )
    )
    script = (
        "import numpy as np, recmod;"
        "print(recmod.total(recmod.Pair(np.ones(3), 1.0)), sum(recmod.total.stats.cache_hits.values()))"
    )
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), *sys.path])
    runs = [
        subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True)
        for _ in range(2)
    ]
    assert [r.returncode for r in runs] == [0, 0], runs[0].stderr + runs[1].stderr
    assert [r.stdout.split() for r in runs] == [["4.0", "0"], ["4.0", "1"]]
