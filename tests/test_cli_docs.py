"""The command lines as docs/commands.md gives them (its synopsis block and its tables), against
the programs: mrsim's usage line, and every subcommand, bench and option of `pymr` (from its own
parser); and docs/architecture.md's Python API against `import pymr`."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

import pymr
from pymr.cli import build_parser

ROOT = Path(__file__).resolve().parent.parent
COMMANDS = (ROOT / "docs" / "commands.md").read_text()
ARCHITECTURE = (ROOT / "docs" / "architecture.md").read_text()
README = (ROOT / "README.md").read_text()


def readme_usage_block() -> str:
    """The fenced block of docs/commands.md's 'Synopsis' section."""
    section = COMMANDS.split("\n## Synopsis\n", 1)[1]
    return section.split("```\n", 2)[1]


def pymr_table() -> str:
    """docs/commands.md's section 'The `pymr` command line': its table of subcommands."""
    return COMMANDS.split("\n## The `pymr` command line\n", 1)[1].split("\n## ", 1)[0]


def subcommands() -> dict:
    action = next(a for a in build_parser()._actions if a.dest == "command")
    return action.choices


def mentions(text: str, option: str) -> bool:
    text = re.sub(r"--\[no-\](\w+)", r"--\1 --no-\1", text)
    return re.search(r"(?<![\w-])" + re.escape(option) + r"(?![\w-])", text) is not None


def entries(text: str, name: str) -> str:
    """The lines of `text` about `pymr NAME`: each line that starts it, and its continuations."""
    out, inside = [], False
    for line in text.splitlines():
        if re.match(rf"(\| `)?pymr {re.escape(name)}\b", line):
            inside = True
        elif not line.startswith(" "):
            inside = False
        if inside:
            out.append(line)
    return "\n".join(out)


def test_mrsim_usage_is_the_documented_one(mrsim):
    r = subprocess.run([mrsim, "--help"], capture_output=True, text=True, timeout=30)
    assert r.returncode == 0
    usage = r.stdout.strip().removeprefix("usage: ").removesuffix(" | --version")
    assert readme_usage_block().splitlines()[0] == usage
    assert f"```\n{usage}\n```" in COMMANDS


@pytest.mark.parametrize("name", list(subcommands()))
def test_every_pymr_subcommand_and_option_is_documented(name):
    """Each subcommand has its line in commands.md's synopsis block and a row in its table of
    `pymr` subcommands, and both name every option it takes (short or long form)."""
    parser = subcommands()[name]
    readme, arch = entries(readme_usage_block(), name), entries(pymr_table(), name)
    assert readme, f"docs/commands.md synopsis: no line for pymr {name}"
    assert arch, f"docs/commands.md table: no row for pymr {name}"
    for action in parser._actions:
        if not action.option_strings or "--help" in action.option_strings:
            continue
        for where, text in (("docs/commands.md synopsis", readme), ("docs/commands.md table", arch)):
            assert any(mentions(text, o) for o in action.option_strings), \
                f"{where}: pymr {name} does not mention {'/'.join(action.option_strings)}"


def test_every_bench_is_documented():
    bench = subcommands()["bench"]
    what = next(a for a in bench._actions if a.dest == "what")
    for choice in what.choices:
        assert f"pymr bench {choice}" in readme_usage_block()
        assert choice in entries(pymr_table(), "bench")
        assert f"{choice}:" in what.help, f"pymr bench --help does not describe {choice}"


def test_every_public_name_is_in_the_python_api_section():
    """architecture.md's Python API names everything `import pymr` gives (pymr.__all__)."""
    missing = [n for n in pymr.__all__ if n != "__version__"
               and f"`pymr.{n}" not in ARCHITECTURE and f"`{n}`" not in ARCHITECTURE]
    assert not missing, f"docs/architecture.md does not describe pymr.{', pymr.'.join(missing)}"


def test_the_readme_tank_summary_is_what_pymr_run_prints(tmp_path):
    """The README's '$ pymr run input/tank_gun_turret.nml' block, line by line, with the
    timings of its cpu line masked."""
    block = README.split("$ pymr run input/tank_gun_turret.nml\n", 1)[1].split("```", 1)[0]
    r = subprocess.run(["pymr", "run", str(ROOT / "input" / "tank_gun_turret.nml")], capture_output=True,
                       text=True, cwd=tmp_path, timeout=120)
    assert r.returncode == 0, r.stderr

    def masked(text):
        return [re.sub(r"\d+\.\d+(e-?\d+)?", "T", ln) if ln.startswith("cpu time") else ln
                for ln in text.strip("\n").splitlines()]

    assert masked(r.stdout) == masked(block)
