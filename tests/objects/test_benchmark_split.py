"""The benchmark split: a fixed, recorded set of embedded objects that every profile holds out."""

import yaml

from dexlite_pipeline.objects.sources import (
    BENCHMARK_SPLIT_FILE,
    benchmark_object_ids,
    builtin_sources,
    collect_sources,
    random_pybullet_paths,
)


def test_the_split_has_at_least_40_existing_procedural_objects():
    ids = benchmark_object_ids()
    procedural = {f"pb-random-{p.stem}" for p in random_pybullet_paths()}
    assert len(ids) >= 40 and ids <= procedural
    record = yaml.safe_load(BENCHMARK_SPLIT_FILE.read_text())
    assert record["rule"] and record["made_by"] and len(record["object_ids"]) == len(ids)


def test_benchmark_objects_are_held_out_wherever_they_are_drawn():
    ids = benchmark_object_ids()
    every_builtin = collect_sources(2000, [], [], seed=0, benchmark_heldout=True)
    drawn = {s.object_id: s.always_heldout for s in every_builtin}
    assert ids <= set(drawn)
    assert all(drawn[o] for o in ids) and not any(held for o, held in drawn.items() if o not in ids)
    assert not any(s.always_heldout for s in collect_sources(2000, [], [], seed=0, benchmark_heldout=False))


def test_the_default_run_draws_none_of_them():
    """The split was drawn outside the default run's objects (40 objects, seeds 0-2), so that run keeps its split."""
    for seed in (0, 1, 2):
        assert not {s.object_id for s in builtin_sources(40, seed)} & benchmark_object_ids()
