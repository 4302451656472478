"""The README's commands, files and links exist: what it tells a user to type works as written.

Checked in the README's code (fenced blocks and `inline code`):
- every `dexlite SUBCOMMAND` is a subcommand of the CLI, and every option given to it is one
  the subcommand accepts;
- every Snakemake target is a rule, every `--profile` a profile folder, every
  `--configfile` a file of the repository (or one the same block writes first);
- every repository path it names exists, and every `section.key` of the config is a key of
  config.yaml;
- the test command is the one `.ci/run` runs.
The README opens with the one-mesh command, and carries no run log (dates, commits: those are in
docs/results.md). In README.md and docs/*.md: every relative link and image exists, nothing points
outside the repository, and the write-up this project follows is never called plain "DexLite".
"""

import argparse
import importlib
import re
import shlex
from pathlib import Path

import pytest
import yaml

from dexlite_pipeline.cli import COMMANDS

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = sorted((ROOT / "docs").glob("*.md"))
TEST_COMMAND = "bash install.sh --test && .venv/bin/python -m pytest -q"
# Top-level entries of the repository a README path may start with (outputs under results/ are not in it).
REPO_ENTRIES = ("config", "config.yaml", "profiles", "envs", "src", "workflow", "docs", "benchmarks", "tests", "install.sh", "Snakefile", ".ci")
# Snakemake options that take one value, and those that take several (up to the next option).
SNAKEMAKE_ONE_VALUE = {"--cores", "-c", "--jobs", "-j", "--profile", "--sdm", "--rerun-triggers", "--forcerun", "-R", "--until", "--directory", "-d", "--slurm-status-command"}
SNAKEMAKE_MANY_VALUES = {"--config", "-C", "--configfile", "--configfiles"}


def code_blocks(text: str) -> list[str]:
    """Fenced code blocks, then inline code spans (outside the fences)."""
    fenced = re.findall(r"^```[^\n]*\n(.*?)^```", text, flags=re.M | re.S)
    rest = re.sub(r"^```[^\n]*\n.*?^```", "", text, flags=re.M | re.S)
    return fenced + re.findall(r"`([^`\n]+)`", rest)


def code_blocks_fenced(text: str) -> list[str]:
    """The fenced code blocks, in order."""
    return re.findall(r"^```[^\n]*\n(.*?)^```", text, flags=re.M | re.S)


def command_lines(block: str) -> list[str]:
    """Shell commands of a block: comments dropped, continuation lines joined, split at && ; |."""
    lines = re.sub(r"\\\n", " ", block).splitlines()
    commands = []
    for line in lines:
        line = line.split(" #")[0] if not line.lstrip().startswith("#") else ""
        commands += [part.strip() for part in re.split(r"&&|;|\|", line) if part.strip()]
    return commands


def words(command: str) -> list[str]:
    try:
        return shlex.split(command)
    except ValueError:
        return command.split()


def rule_names() -> set[str]:
    names = set()
    for path in [ROOT / "Snakefile", *sorted((ROOT / "workflow" / "rules").glob("*.smk"))]:
        names |= set(re.findall(r"^(?:rule|checkpoint) (\w+):", path.read_text(), flags=re.M))
    return names


def stage_options(subcommand: str) -> set[str]:
    """Option strings the subcommand's parser accepts (as the CLI builds it)."""
    module = importlib.import_module(f"dexlite_pipeline.{COMMANDS[subcommand][0]}")
    parser = argparse.ArgumentParser()
    parser.add_argument("--threads")
    module.add_arguments(parser)
    return set(parser._option_string_actions)


def readme_commands() -> list[tuple[list[str], str]]:
    """(words, the whole block) of every command line in the README's code."""
    out = []
    for block in code_blocks(README.read_text()):
        out += [(words(command), block) for command in command_lines(block)]
    return out


def test_readme_has_the_ci_test_command():
    assert TEST_COMMAND in README.read_text()
    ci = (ROOT / ".ci" / "run").read_text()
    for part in TEST_COMMAND.split(" && "):
        assert part in ci, f".ci/run does not run {part!r}"


def test_dexlite_subcommands_and_options_exist():
    seen = set()
    for tokens, _ in readme_commands():
        for k, token in enumerate(tokens[:-1]):
            if token != "dexlite" or tokens[k + 1].startswith("-"):
                continue
            subcommand = tokens[k + 1]
            assert subcommand in COMMANDS, f"README: `dexlite {subcommand}` is not a subcommand ({', '.join(COMMANDS)})"
            seen.add(subcommand)
            options = stage_options(subcommand)
            for option in tokens[k + 2 :]:
                if option.startswith("--"):
                    assert option.split("=")[0] in options, f"README: `dexlite {subcommand}` has no option {option}"
    assert {"grasp", "export-dexgraspnet", "import-dexgraspnet"} <= seen


def test_dexlite_usage_line_matches_the_cli():
    """The documented usage of `dexlite grasp` ([--n N] ...) names options the command has."""
    text = README.read_text()
    usage = re.search(r"`dexlite grasp (MESH[^`]*)`", text)
    assert usage, "README: no usage line of dexlite grasp"
    options = stage_options("grasp")
    for option in re.findall(r"--[a-z][a-z-]*", usage.group(1)):
        assert option in options, f"README: dexlite grasp has no option {option}"


def test_snakemake_targets_profiles_and_configfiles_exist():
    rules = rule_names()
    checked = 0
    for tokens, block in readme_commands():
        if "snakemake" not in tokens:
            continue
        written = set(re.findall(r">\s*(\S+)", block))  # files the same block writes first (printf ... > my.yaml)
        args = tokens[tokens.index("snakemake") + 1 :]
        k, many = 0, False
        while k < len(args):
            arg = args[k]
            if arg.startswith("-"):
                name = arg.split("=")[0]
                many = name in SNAKEMAKE_MANY_VALUES
                if name in SNAKEMAKE_ONE_VALUE or many:
                    value = arg.split("=", 1)[1] if "=" in arg else (args[k + 1] if k + 1 < len(args) else "")
                    if name == "--profile":
                        assert (ROOT / value / "config.yaml").is_file(), f"README: profile {value} does not exist"
                    if name in ("--configfile", "--configfiles"):
                        assert (ROOT / value).is_file() or value in written, f"README: config file {value} does not exist"
                    k += 1 if "=" in arg else 2
                    continue
                k += 1
                continue
            if many:  # a further value of --config/--configfile
                if "=" not in arg and not arg.endswith((".yaml", ".yml")):
                    many = False
                else:
                    if arg.endswith((".yaml", ".yml")):
                        assert (ROOT / arg).is_file() or arg in written, f"README: config file {arg} does not exist"
                    k += 1
                    continue
            assert arg in rules, f"README: snakemake target {arg!r} is not a rule ({', '.join(sorted(rules))})"
            checked += 1
            k += 1
    assert checked >= 3  # the run, the configfile example and the cluster run name their target


def test_repository_paths_and_config_keys_exist():
    config = yaml.safe_load((ROOT / "config.yaml").read_text())
    paths = keys = 0
    for code in code_blocks(README.read_text()):
        for token in re.findall(r"[\w./*<>-]+", code):
            token = token.rstrip(".")
            first = token.split("/")[0]
            if first in REPO_ENTRIES and "<" not in token and "*" not in token and (token != first or "." in first):
                assert (ROOT / token).exists(), f"README names {token}, which is not in the repository"
                paths += 1
            section, _, key = token.partition(".")
            if key and section in config and isinstance(config[section], dict) and re.fullmatch(r"[a-z_]+", key):
                assert key in config[section], f"README names config key {token}, which config.yaml does not have"
                keys += 1
    assert paths >= 5 and keys >= 3


@pytest.mark.parametrize("path", [README, *DOCS], ids=lambda p: p.name)
def test_links_and_images_exist_and_stay_in_the_repository(path):
    text = path.read_text()
    targets = re.findall(r"!?\[[^\]]*\]\(([^)\s]+)\)", text)
    for target in targets:
        if re.match(r"[a-z]+://", target) or target.startswith("#"):
            continue
        resolved = (path.parent / target.split("#")[0]).resolve()
        assert resolved.is_relative_to(ROOT), f"{path.name}: link {target} leaves the repository"
        assert resolved.exists(), f"{path.name}: link {target} does not exist"
    for pattern in (r"\.\./shared", r"DESIGN\.md", r"[Ss]ession [0-9]", r"previous commit"):
        assert not re.search(pattern, text), f"{path.name} refers to {pattern}"


def test_readme_images_are_pictures():
    images = re.findall(r"!\[[^\]]*\]\(([^)\s]+)\)", README.read_text())
    assert "docs/heldout_optimized_grasp.png" in images and "docs/report_first_screen.png" in images  # a grasp and the report
    for image in images:
        assert (ROOT / image).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", image


def test_first_command_block_grasps_a_mesh():
    first = code_blocks_fenced(README.read_text())[0]
    tokens = words(command_lines(first)[0])
    assert tokens[:2] == ["dexlite", "grasp"] and "--out" in tokens, f"README: the first command block is {first!r}"


def test_readme_has_no_run_log():
    text = README.read_text()
    for pattern, what in ((r"\b20\d\d-\d\d-\d\d\b", "a date"), (r"\bat [0-9a-f]{7}\b", "a commit"), (r"training seeds? \d", "per-seed numbers")):
        assert not re.search(pattern, text), f"README carries {what} ({re.search(pattern, text).group(0)!r}): it belongs in docs/results.md"


@pytest.mark.parametrize("path", [README, *DOCS], ids=lambda p: p.name)
def test_the_write_up_has_its_own_name(path):
    """"DexLite" is this project; the write-up it follows is "the DexLite write-up (Murali)" / "the write-up"."""
    text = path.read_text()
    for pattern in (r"DexLite['’]s", r"DexLite report", r"DexLite,? a lightweight", r"of DexLite\b"):
        assert not re.search(pattern, text), f"{path.name}: {re.search(pattern, text).group(0)!r} (call the write-up 'the DexLite write-up (Murali)' or 'the write-up')"
