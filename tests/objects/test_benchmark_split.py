"""The benchmark split: a fixed, recorded set of embedded objects that every profile holds out."""

import pytest
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


def test_benchmark_objects_adds_the_first_objects_of_the_split_held_out():
    from dexlite_pipeline.objects.sources import ObjectSourceError, benchmark_object_list

    first = benchmark_object_list()[:3]
    added = collect_sources(40, [], [], seed=0, benchmark_heldout=True, benchmark_objects=3)
    assert [s.object_id for s in added[-3:]] == first and all(s.always_heldout for s in added[-3:])
    assert len(added) == 43 and len({s.object_id for s in added}) == 43
    # an object the draw already holds is not added twice
    everything = collect_sources(2000, [], [], seed=0, benchmark_heldout=True, benchmark_objects=3)
    assert len(everything) == len({s.object_id for s in everything}) == len(collect_sources(2000, [], [], seed=0, benchmark_heldout=True))
    with pytest.raises(ObjectSourceError, match="objects.benchmark_objects"):
        collect_sources(0, [], [], seed=0, benchmark_objects=len(benchmark_object_list()) + 1)
