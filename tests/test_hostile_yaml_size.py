"""Large YAML files: bounded while libyaml streams them (a 10 000-row D-H table refused in milliseconds instead of
after a 3-24 s parse), while a 30 000-point sweep list within the size limits is read; every earlier protection
(node cap, alias bombs, recursive aliases, depth, duplicate keys, octal numbers) still holds."""

from __future__ import annotations

from pathlib import Path

import pytest

from redundik.config import yamlio
from redundik.config.yamlio import MAX_DEPTH, MAX_NODES, MAX_TOP_LEVEL_LIST, read_yaml
from redundik.errors import ConfigError

needs_libyaml = pytest.mark.skipif(yamlio._CLoader is None, reason="PyYAML without libyaml: the bounded pure parser")


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "f.yaml"
    path.write_text(text)
    return path


def test_a_ten_thousand_row_dh_table_is_refused_before_the_rest_is_parsed(tmp_path: Path) -> None:
    rows = "".join(f"  - {{name: 'j{i}', type: revolute, a: 1, alpha: 0}}\n" for i in range(10_000))
    path = _write(tmp_path, "name: big\ndh:\n" + rows)
    with pytest.raises(ConfigError, match=rf"f\.yaml:(\d+): .*'dh' has more than {MAX_TOP_LEVEL_LIST['dh']}") as info:
        read_yaml(path)
    line = int(str(info.value).split(":")[1])
    assert line <= MAX_TOP_LEVEL_LIST["dh"] + 5  # refused where the bound was crossed, not at the end of the file


def test_a_thirty_thousand_point_sweep_list_is_read(tmp_path: Path) -> None:
    points = ",".join(f"[{i * 1e-4:.4f}, 0.1, 0.2]" for i in range(30_000))
    data = read_yaml(_write(tmp_path, f"name: s\npoints: [{points}]\n"))
    assert len(data["points"]) == 30_000 and data["points"][-1] == [2.9999, 0.1, 0.2]


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("name: x\nq0: [" + ",".join(["0"] * (MAX_NODES + 10)) + "]\n", f"more than {MAX_NODES} values"),
        ("a: &a [1, 2]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a, *a]\n"
         + "".join(f"c{k}: &c{k} [" + ", ".join([f"*{'b' if k == 0 else f'c{k - 1}'}"] * 10) + "]\n" for k in range(6)),
         "expands to more than"),
        ("a: &a [1, *a]\n", "recursive alias|found undefined alias"),
        ("z: " + "[" * (MAX_DEPTH + 5) + "]" * (MAX_DEPTH + 5) + "\n", f"nesting deeper than {MAX_DEPTH}"),
        ("a: 1\na: 2\n", "duplicate key 'a'"),
        ("a: 010\n", "octal"),
        ("a: 1:30\n", "base 60"),
        ("a: [1, 2\n", "invalid YAML"),
    ],
)  # fmt: skip
def test_every_earlier_protection_still_holds(tmp_path: Path, text: str, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        read_yaml(_write(tmp_path, text))


def test_yaml_12_exponent_floats_still_read_as_numbers(tmp_path: Path) -> None:
    assert read_yaml(_write(tmp_path, "steps: 1e3\nx: -2E-3\n")) == {"steps": 1000.0, "x": -0.002}


@needs_libyaml
def test_the_fast_loader_builds_what_the_bounded_pure_loader_builds(tmp_path: Path) -> None:
    text = (Path(__file__).resolve().parents[1] / "tasks" / "planar3r_line.yaml").read_text()
    pure = yamlio.BoundedLoader(text)
    try:
        assert yamlio.parse_yaml(text, "x") == pure.get_single_data()
    finally:
        pure.dispose()
