"""benchmarks/experiments/loop_round_yield.py: variant settings and the refusal of a run folder without the round's inputs."""

from pathlib import Path

import pytest


def test_a_variant_is_a_name_and_nested_yaml_settings(benchmark_script):
    script = benchmark_script("loop_round_yield")
    assert script.parse_variant("debiased") == ("debiased", {})
    name, overlay = script.parse_variant("m16:loop.anchor_rule=matched,loop.match_candidates=16,sample.debias_codes=false")
    assert name == "m16"
    assert overlay == {"loop": {"anchor_rule": "matched", "match_candidates": 16}, "sample": {"debias_codes": False}}


@pytest.mark.parametrize("bad", [":loop.rounds=1", "a/b", "x:loop.rounds"])
def test_a_malformed_variant_is_refused(bad, benchmark_script):
    with pytest.raises(SystemExit, match="--variant"):
        benchmark_script("loop_round_yield").parse_variant(bad)


def test_a_variant_outside_the_schema_is_refused_before_any_work(tmp_path, benchmark_script):
    from dexlite_pipeline.config import DEFAULT_CONFIG_PATH, ConfigError

    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "config.yaml").write_text(Path(DEFAULT_CONFIG_PATH).read_text())
    with pytest.raises(ConfigError, match="anchor_rule"):
        benchmark_script("loop_round_yield").main([str(tmp_path / "run"), str(tmp_path / "out"), "--variant", "bad:loop.anchor_rule=nearest"])
    assert not (tmp_path / "out").exists()


def test_a_run_folder_without_the_rounds_inputs_is_refused(tmp_path, benchmark_script):
    from dexlite_pipeline.config import DEFAULT_CONFIG_PATH

    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "config.yaml").write_text(Path(DEFAULT_CONFIG_PATH).read_text())
    with pytest.raises(SystemExit, match="does not exist"):
        benchmark_script("loop_round_yield").main([str(tmp_path / "run"), str(tmp_path / "out"), "--variant", "debiased"])
