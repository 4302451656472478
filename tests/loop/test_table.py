"""The loop table: one row per round, in round order."""

from __future__ import annotations

from dexlite_pipeline.loop.table import loop_table


def test_loop_table_orders_rounds():
    table = loop_table([{"round": 2, "grasps": 5}, {"round": 0, "grasps": 3}])
    assert table["round"].tolist() == [0, 2] and "heldout_distinct_per_object" in table.columns
