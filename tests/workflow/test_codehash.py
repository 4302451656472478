"""code_hash: a stage's hash follows exactly the package code it imports."""

from pathlib import Path

import pytest

from dexlite_pipeline.codehash import code_hash, module_closure

FAKE_PACKAGE = {
    "__init__.py": '"""pkg"""\n',
    "util.py": "def helper():\n    return 1\n",
    "unrelated.py": "VALUE = 3\n",
    "sim/__init__.py": "from .engine import step\n",
    "sim/engine.py": "import numpy\nfrom dexlite_pipeline.util import helper\n\ndef step():\n    return helper()\n",
    "sim/extra.py": "EXTRA = 1\n",
    "stages/__init__.py": "",
    "stages/lift.py": "def run(args):\n    from ..sim import extra\n    from dexlite_pipeline import sim\n    return sim.step() + extra.EXTRA\n",
    "stages/prepare.py": "import dexlite_pipeline.util as u\n\ndef run(args):\n    return u.helper()\n",
}


@pytest.fixture()
def fake_root(tmp_path) -> Path:
    root = tmp_path / "dexlite_pipeline"
    for rel, text in FAKE_PACKAGE.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)
    return root


def test_closure_follows_absolute_relative_and_lazy_imports(fake_root):
    closure = module_closure("dexlite_pipeline.stages.lift", root=fake_root)
    assert set(closure) == {
        "dexlite_pipeline",
        "dexlite_pipeline.stages",
        "dexlite_pipeline.stages.lift",
        "dexlite_pipeline.sim",
        "dexlite_pipeline.sim.engine",
        "dexlite_pipeline.sim.extra",
        "dexlite_pipeline.util",
    }
    prepare = module_closure("dexlite_pipeline.stages.prepare", root=fake_root)
    assert "dexlite_pipeline.sim.engine" not in prepare and "dexlite_pipeline.util" in prepare


def test_hash_changes_with_imported_code_only(fake_root):
    lift_before = code_hash("dexlite_pipeline.stages.lift", root=fake_root)
    prepare_before = code_hash("dexlite_pipeline.stages.prepare", root=fake_root)

    engine = fake_root / "sim" / "engine.py"
    engine.write_text(engine.read_text() + "# a comment and blank lines change nothing\n\n")
    assert code_hash("dexlite_pipeline.stages.lift", root=fake_root) == lift_before

    engine.write_text(engine.read_text().replace("return helper()", "return helper() + 1"))
    assert code_hash("dexlite_pipeline.stages.lift", root=fake_root) != lift_before
    assert code_hash("dexlite_pipeline.stages.prepare", root=fake_root) == prepare_before

    (fake_root / "unrelated.py").write_text("VALUE = 4\n")
    assert code_hash("dexlite_pipeline.stages.prepare", root=fake_root) == prepare_before


def test_unknown_module_is_an_error(fake_root):
    with pytest.raises(ModuleNotFoundError, match="no_such_stage"):
        code_hash("dexlite_pipeline.stages.no_such_stage", root=fake_root)


def test_real_package_closure_is_exact():
    """On the installed package: a module importing nothing from it has just itself and the root."""
    assert list(module_closure("dexlite_pipeline.codehash")) == ["dexlite_pipeline", "dexlite_pipeline.codehash"]
    assert len(code_hash("dexlite_pipeline.codehash")) == 16


REPO = Path(__file__).resolve().parents[2]
PACKAGE_ROOT = REPO / "src" / "dexlite_pipeline"
# Light modules the config tree may import besides the config modules: where the shipped model is (sample.shipped_model);
# the asset build settings (config types only, apart so that the asset cache's key does not hash section objects).
CONFIG_TREE_LEAVES = {"dexlite_pipeline.model.shipped", "dexlite_pipeline.objects.asset_settings"}


def test_config_tree_imports_only_config_modules():
    """settings.PipelineConfig and every section class import no component code (only config modules),
    so a stage that reads the typed tree hashes no other component's code. The closure includes
    each package ``__init__`` on the way and what it imports, so a heavy ``__init__`` fails too."""
    closure = module_closure("dexlite_pipeline.settings", root=PACKAGE_ROOT)
    modules = {name for name, path in closure.items() if path.name != "__init__.py"}
    assert {"dexlite_pipeline.energy.config", "dexlite_pipeline.model.config"} <= modules
    for name in modules:
        assert name.rsplit(".", 1)[-1] in ("config", "settings") or name in CONFIG_TREE_LEAVES, f"the config tree imports {name}"


def test_design_doc_lists_each_stage_closure():
    """docs/design.md's list of what each stage's code hash covers is the generated one."""
    from dexlite_pipeline.codehash import closure_markdown

    text = (REPO / "docs" / "design.md").read_text()
    start, end = "<!-- stage closures: start -->\n", "<!-- stage closures: end -->"
    assert start in text and end in text, "docs/design.md lost its stage closure markers"
    listed = text.split(start, 1)[1].split(end, 1)[0]
    assert listed == closure_markdown(PACKAGE_ROOT), "docs/design.md is stale: paste `python -m dexlite_pipeline.codehash --markdown`"
