"""Hostile YAML, refused while it is parsed: YAML 1.1 octal and base-60 numbers (ordinary numbers still read),
merge keys, keys that are not text, dense files and huge D-H tables, each a one-line error with its file, line or key
path."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from redundik.errors import ConfigError
from tests.hostile import HANG_GUARD_S, TASK, Cli, _one_line_error, _write


def test_a_huge_dh_table_is_refused_before_the_model_is_built(cli: Cli, tmp_path: Path) -> None:
    """A 400-row D-H table took 13 s and 6 GB to build (Pinocchio's data grows as n³), 1000 rows were killed."""
    rows = "".join(f'- {{name: "{i}", a: 0.1, alpha: 90}}\n' for i in range(1, 202))
    start = time.perf_counter()
    code, _, err = cli("validate", _write(tmp_path, f"name: big\nangle_unit: deg\ndh:\n{rows}", "r.yaml"))
    assert time.perf_counter() - start < HANG_GUARD_S
    _one_line_error(code, err)
    assert err.startswith("error: r.yaml: dh: at most 200 D-H rows, got 201"), err


def test_a_dense_yaml_file_is_refused_while_it_is_parsed(tmp_path: Path) -> None:
    """480 000 numbers in 0.9 MiB took 15 s of pure-Python parsing before any check; now refused at 100 000."""
    from redundik.config.yamlio import MAX_NODES, read_yaml
    from redundik.errors import ConfigError

    path = _write(tmp_path, "name: x\nq0: [" + ",".join(["0"] * (MAX_NODES + 10)) + "]\n")
    start = time.perf_counter()
    with pytest.raises(ConfigError, match=f"more than {MAX_NODES} values in one file"):
        read_yaml(path)
    assert time.perf_counter() - start < HANG_GUARD_S
    assert read_yaml(_write(tmp_path, "q0: [" + ",".join(["0"] * 1000) + "]\n"))["q0"] == [0] * 1000


def test_yaml_merge_keys_are_refused_in_plain_words(cli: Cli, tmp_path: Path) -> None:
    text = TASK.replace("  rank_only:\n", "  base: &b {resolver: pinv}\n  rank_only:\n    <<: *b\n  xx:\n")
    code, _, err = cli("validate", _write(tmp_path, text))
    _one_line_error(code, err)
    assert "merge keys ('<<: *anchor') are not supported" in err and "tag:yaml.org" not in err


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("q0: [010, -040, -030]\n", "'010': YAML reads a number with a leading zero as octal (= 8)"),
        ("steps: 0500\n", "'0500': YAML reads a number with a leading zero as octal (= 320)"),
        ("steps: 1:30\n", "'1:30': YAML reads numbers with ':' as base 60 (= 90)"),
        ("dt: 190:20:30.15\n", "'190:20:30.15': YAML reads numbers with ':' as base 60"),
    ],
)
def test_yaml_1_1_octal_and_base_60_numbers_are_refused(tmp_path: Path, text: str, expected: str) -> None:
    """PyYAML (YAML 1.1) read ``q0: [010, -040, -030]`` as [8, -32, -24] degrees and ``steps: 1:30`` as 90 steps."""
    from redundik.config.yamlio import read_yaml

    with pytest.raises(ConfigError, match=r"f\.yaml:1: invalid YAML: ") as info:
        read_yaml(_write(tmp_path, text))
    assert expected in str(info.value)


def test_ordinary_numbers_still_read_as_numbers(tmp_path: Path) -> None:
    from redundik.config.yamlio import read_yaml

    data = read_yaml(_write(tmp_path, "a: 0\nb: -0\nc: 10\nd: 1_000\ne: 1e3\nf: 0.5\ng: 00.5\nh: '010'\ni: '1:30'\n"))
    assert data == {"a": 0, "b": 0, "c": 10, "d": 1000, "e": 1000.0, "f": 0.5, "g": 0.5, "h": "010", "i": "1:30"}


def test_an_octal_start_configuration_is_refused_at_its_line(cli: Cli, tmp_path: Path) -> None:
    code, _, err = cli("validate", _write(tmp_path, TASK.replace("q0: [110, -40, -30]", "q0: [110, -040, -030]")))
    _one_line_error(code, err)
    line = TASK.splitlines().index("q0: [110, -40, -30]") + 1
    assert err.startswith(f"error: {tmp_path / 'f.yaml'}:{line}: invalid YAML: '-040': YAML reads a number"), err
    assert "leading zero as octal (= -32)" in err


def test_a_key_that_is_not_text_is_named_in_its_mapping(cli: Cli, tmp_path: Path) -> None:
    """Was ``[1]: Keys should be strings`` (pydantic's words, and the key shown as a list index)."""
    code, _, err = cli("validate", _write(tmp_path, TASK.replace("dt: 0.01", "dt: 0.01\n1: 1")))
    _one_line_error(code, err)
    assert err.startswith("error: (top level): key 1 (a number) is not text"), err
    code, _, err = cli("validate", _write(tmp_path, TASK.replace("dt: 0.01", "dt: 0.01\nnull: 1")))
    _one_line_error(code, err)
    assert err.startswith("error: (top level): key null is not text"), err
