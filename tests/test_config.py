"""Settings a researcher can write down: validation on construction, TOML in (errors name the
file, line and key) and out (with unit, range and source), and the reproduce config built from
defaults, the quick preset and a file."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import pytest

from mbn.cli.main import main
from mbn.config import Settings, read_toml, setting, settings_to_dict
from mbn.errors import MbnInputError
from mbn.experiments.reproduce import REPRODUCE
from mbn.experiments.stages.lf import LFSettings
from mbn.experiments.stages.settings import QUICK


@dataclass(frozen=True)
class Demo(Settings):
    """A demo section."""

    section = "demo"
    count: int = setting(3, doc="how many", low=1, high=10, source="here")
    rate: float = setting(0.5, doc="a rate", unit="1/s", low=0.0)
    mode: str = setting("a", doc="a mode", choices=("a", "b"))
    names: tuple[str, ...] = setting(("x", "y"), doc="names", choices=("x", "y", "z"))
    flag: bool = setting(False, doc="a flag")


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"count": 0}, "demo.count: must be >= 1, got 0"),
        ({"count": 11}, "demo.count: must be <= 10, got 11"),
        ({"count": 2.5}, "demo.count: expected an integer, got 2.5"),
        ({"count": True}, "demo.count: expected an integer, got True"),
        ({"rate": float("inf")}, "demo.rate: expected a finite number, got inf"),
        ({"rate": "fast"}, "demo.rate: expected a finite number, got 'fast'"),
        ({"mode": "c"}, "demo.mode: expected one of a, b, got 'c'"),
        ({"names": ("x", "w")}, r"demo.names\[1\]: expected one of x, y, z, got 'w'"),
        ({"names": "x"}, "demo.names: expected a list of strings, got 'x'"),
        ({"flag": 1}, "demo.flag: expected true or false, got 1"),
    ],
)
def test_settings_are_checked_on_construction(changes, message):
    with pytest.raises(MbnInputError, match=message):
        Demo(**changes)


def test_settings_convert_lists_to_tuples_and_ints_to_floats():
    d = Demo(rate=2, names=["z"])  # type: ignore[arg-type]
    assert d.rate == 2.0 and isinstance(d.rate, float) and d.names == ("z",)
    assert settings_to_dict(d) == {
        "count": 3,
        "rate": 2.0,
        "mode": "a",
        "names": ["z"],
        "flag": False,
    }


def test_every_field_of_the_reproduce_config_has_a_doc_and_its_defaults_are_valid():
    config = REPRODUCE.config()
    for section in config.sections:
        for f in dataclasses.fields(section):
            assert f.metadata.get("doc"), f"{section.section}.{f.name} has no doc"
    # the quick preset names real settings
    for name, values in QUICK.items():
        assert set(values) <= {f.name for f in dataclasses.fields(config[name])}, name


def test_a_settings_file_overrides_the_defaults_and_the_quick_preset(tmp_path):
    path = tmp_path / "my.toml"
    path.write_text("[rf]\ngenerations = 7\n\n[tests]\nmaze = 'heldout'\n")
    config = REPRODUCE.config(quick=True, document=read_toml(path))
    assert config["rf"].generations == 7  # the file wins over the preset
    assert config["rf"].variants == QUICK["rf"]["variants"]  # the preset over the default
    assert config["tests"].maze == "heldout"
    assert config["lf"].generations == QUICK["lf"]["generations"]
    assert config.quick and config["run"].precision == "float32"
    full = REPRODUCE.config(document=read_toml(path))
    assert full["lf"].generations == LFSettings().generations and not full.quick
    # [run] quick = true in the file is --quick
    path.write_text("[run]\nquick = true\n")
    assert REPRODUCE.config(document=read_toml(path)) == REPRODUCE.config(quick=True)


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[rf]\ngenerations = 10\n\nspeed = 3\n", r"s\.toml:4: rf\.speed: unknown setting"),
        ("[rf]\ngenerations = -1\n", r"s\.toml:2: rf\.generations: must be >= 0, got -1"),
        ("[rff]\ngenerations = 1\n", r"s\.toml:1: \[rff\]: unknown section"),
        (
            "[pm]\nreward = 'best'\n",
            r"s\.toml:2: pm\.reward: expected one of programs, memory, paper",
        ),
        ("[pm]\ninit = 20.0\n", r"s\.toml:2: pm\.init must be in \(0, pm\.bound\]"),
        ("[lf]\napproaches = ['north']\n", r"s\.toml:2: lf\.approaches\[0\]: expected one of"),
        ("[rf\ngenerations = 1\n", r"s\.toml:1: TOML syntax error"),
        ("[rf]\ngenerations = 1\ngenerations = 2\n", r"s\.toml:3: TOML syntax error"),
        ("rf = 3\n", r"s\.toml: \[rf\]: expected a table, got 3"),
    ],
)
def test_a_bad_settings_file_is_one_line_naming_file_line_and_key(tmp_path, text, message):
    path = tmp_path / "s.toml"
    path.write_text(text)
    with pytest.raises(MbnInputError, match=message):
        REPRODUCE.config(document=read_toml(path))


def test_a_settings_file_that_is_not_utf8_is_refused(tmp_path):
    path = tmp_path / "s.toml"
    path.write_bytes(b"[rf]\ngenerations = 1 # \xff\n")
    with pytest.raises(MbnInputError, match=r"s\.toml: not UTF-8 text"):
        read_toml(path)


def test_print_config_prints_every_setting_and_reads_back_to_the_same_config(tmp_path, capsys):
    assert main(["reproduce", "--quick", "--print-config"]) == 0
    text = capsys.readouterr().out
    assert "[rf]" in text and "generations = 15" in text
    assert "# DE generations" in text and "source: paper 3.1" in text
    assert "# length of a training episode; unit: s; range [0.1, 3600]" in text
    path = tmp_path / "printed.toml"
    path.write_text(text)
    assert REPRODUCE.config(document=read_toml(path)) == REPRODUCE.config(quick=True)
    assert not (tmp_path / "runs").exists()


def test_a_bad_config_file_on_the_command_line_is_one_line_and_exit_2(tmp_path, capsys):
    path = tmp_path / "bad.toml"
    path.write_text("[de]\nF = 3.0\n")
    out = tmp_path / "run"
    assert main(["reproduce", "--config", str(path), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "bad.toml:2: de.F: must be <= 2, got 3.0" in err
    assert not out.exists()
    assert main(["reproduce", "--config", str(tmp_path / "none.toml")]) == 2
    assert "none.toml: cannot read" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (
            "[rf]\ngenerations = " + "9" * 400 + "\n",
            r"rf\.generations: 400-digit integer is too large",
        ),
        ("[de]\nF = " + "9" * 400 + "\n", r"de\.F: 400-digit integer is too large"),
        ("[de]\nF = " + "9" * 5000 + "\n", r"invalid TOML \(Exceeds the limit"),
        ("[rf]\ngenerations = 1000000000\n", r"rf\.generations: must be <= 100000"),
        ("[tests]\nseconds = 1e12\n", r"tests\.seconds: must be <= 3600"),
    ],
)
def test_absurd_numbers_in_a_settings_file_are_refused_in_one_line(tmp_path, text, message):
    path = tmp_path / "s.toml"
    path.write_text(text)
    with pytest.raises(MbnInputError, match=message) as exc:
        REPRODUCE.config(document=read_toml(path))
    assert len(str(exc.value)) < 200


@pytest.mark.parametrize(
    "command",
    [
        ["reproduce"],
        ["run", "new-behaviours"],
        ["run", "noise"],
        ["run", "ablations"],
        ["run", "programs-vs-dynamics"],
    ],
)
def test_print_config_is_plain_toml_with_whole_sentences(command, capsys):
    """Every table's description is the first paragraph of its docstring, whole (it ends with
    a full stop) and without reST markup; the whole text parses as TOML."""
    import tomllib

    assert main([*command, "--print-config"]) == 0
    text = capsys.readouterr().out
    data = tomllib.loads(text)
    assert "`" not in text
    assert ":mod:" not in text and ":class:" not in text
    lines = text.splitlines()
    headers = [i for i, line in enumerate(lines) if line.startswith("[")]
    assert [lines[i].strip("[]") for i in headers] == list(data)
    for i in headers:
        assert lines[i] == f"[{lines[i].strip('[]')}]", lines[i]  # no comment cut after it
        above = []
        k = i - 1
        while k >= 0 and lines[k].startswith("# "):
            above.insert(0, lines[k][2:])
            k -= 1
        assert above, f"{lines[i]} has no description"
        assert above[-1].endswith((".", ".)")), f"{lines[i]}: {above[-1]!r} ends mid-sentence"
        assert all(len(line) <= 99 for line in lines[k + 1 : i])
