"""The report page: the result sentence and the wide table of measures, the success chart, the learning ladder, the pictured grasps."""

import numpy as np
import pandas as pd
import pytest
from report_synthetic import OBJECT_ID, grasp_poses

from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.report.inputs import ReportInputs
from dexlite_pipeline.report.page import build_report_html, run_settings_html, training_run_text
from dexlite_pipeline.report.pictures import outcome_of, pick_examples
from dexlite_pipeline.report.plots import OBJECT_MARKER_LABEL, success_figure
from dexlite_pipeline.report.tables import headline_rows, headline_sentence, ladder_html, measures_table_html
from dexlite_pipeline.evaluation.labels import method_label, percent_text, seconds_text


def _metrics(six_dir_rate: float) -> pd.DataFrame:
    return pd.DataFrame({
        "method": ["cvae_raw", "cvae_post"], "split": ["heldout", "heldout"],
        "lift_success_rate": [0.2, 0.4], "object_success_rate": [0.4, 0.8], "six_dir_success_rate": [six_dir_rate, six_dir_rate],
        "lift_success_ci95_low": [0.15, 0.35], "lift_success_ci95_high": [0.25, 0.45],  # Wilson: narrow
        "lift_success_boot_ci95_low": [0.0, 0.1], "lift_success_boot_ci95_high": [0.6, 0.9],  # objects resampled: wide
        "six_dir_success_ci95_low": [np.nan, np.nan], "six_dir_success_ci95_high": [np.nan, np.nan],
        "six_dir_success_boot_ci95_low": [np.nan, np.nan], "six_dir_success_boot_ci95_high": [np.nan, np.nan],
    })  # fmt: skip


def _run_metrics() -> pd.DataFrame:
    """Four methods on 5 held-out objects, 80 grasps each, shaped like metrics.csv."""
    rows = []
    for method, lift, six, seconds in (("optimization", 0.55, 0.5, 0.35), ("cvae_raw", 0.0625, 0.0, 0.003), ("cvae_post", 0.175, 0.1375, 0.021),
                                       ("random_post", 0.2125, 0.0875, 0.024)):  # fmt: skip
        rows.append({
            "method": method, "split": "heldout", "n_grasps": 80, "n_invalid": 0, "n_objects": 5,
            "lift_success_rate": lift, "lift_success_boot_ci95_low": max(0.0, lift - 0.1), "lift_success_boot_ci95_high": lift + 0.11,
            "lift_success_ci95_low": max(0.0, lift - 0.08), "lift_success_ci95_high": lift + 0.09, "object_success_rate": 0.8,
            "six_dir_success_rate": six, "six_dir_success_boot_ci95_low": max(0.0, six - 0.05), "six_dir_success_boot_ci95_high": six + 0.1,
            "penetration_mean_mm": 2.5, "contact_distance_mean_mm": 1.3, "seconds_per_grasp": seconds,
        })  # fmt: skip
    return pd.DataFrame(rows)


def _bar_containers(fig):
    from matplotlib.container import BarContainer

    return {c.get_label(): c for c in fig.axes[0].containers if isinstance(c, BarContainer)}


def _bars(fig) -> dict[str, list[float]]:
    return {label: [patch.get_width() for patch in container.patches] for label, container in _bar_containers(fig).items()}


def test_six_direction_rate_not_measured_gets_no_bar_but_a_not_run_mark():
    fig = success_figure(_metrics(np.nan))
    bars = _bars(fig)
    assert "six-direction test" not in bars and bars["lift test"] == [40.0, 20.0]  # the post-optimized samples first
    assert [t.get_text() for t in fig.axes[0].texts].count("not run") == 2
    assert "six-direction test (not run)" in [t.get_text() for t in fig.axes[0].get_legend().get_texts()]


def test_measured_zero_is_still_a_bar():
    assert _bars(success_figure(_metrics(0.0)))["six-direction test"] == [0.0, 0.0]


def test_error_bars_are_the_object_bootstrap_interval():
    fig = success_figure(_metrics(np.nan))
    lift = _bar_containers(fig)["lift test"]
    segments = lift.errorbar.lines[2][0].get_segments()
    assert [(float(s[0][0]), float(s[1][0])) for s in segments] == [(10.0, 90.0), (0.0, 60.0)]
    assert "bootstrap" in fig.axes[0].get_title()


def test_objects_with_one_success_are_a_marker_not_a_bar():
    fig = success_figure(_metrics(0.1))
    assert set(_bars(fig)) == {"lift test", "six-direction test"}
    marker = next(line for line in fig.axes[0].get_lines() if line.get_label() == OBJECT_MARKER_LABEL)
    assert sorted(marker.get_xdata().tolist()) == [40.0, 80.0]
    # readable method names on the axis, not the ids
    assert {t.get_text() for t in fig.axes[0].get_yticklabels()} == {"CVAE samples, raw", "CVAE samples + post-optimization"}


def test_method_labels_and_cell_texts():
    assert method_label("random_post") == "Random start + post-optimization"
    assert method_label("cvae_recon_post") == "CVAE reconstructions + post-optimization"
    assert method_label("cvae_prior_heldout_post") == "CVAE prior heldout + post-optimization"  # fallback for new ids
    assert percent_text(0.175) == "17.5%" and percent_text(np.nan) == "not run" and percent_text(None) == "not run"
    assert seconds_text(0.35) == "0.35 s" and seconds_text(0.021) == "21 ms" and seconds_text(0.003) == "3 ms" and seconds_text(np.nan) == "—"


def test_headline_sentence_gives_both_rates_of_the_product_and_the_comparisons():
    sentence = headline_sentence(headline_rows(_run_metrics()), {})
    assert sentence.startswith("On 5 held-out objects (80 grasps), 17.5% of CVAE samples + post-optimization held the object in the lift test")
    assert "13.8% against pushes from all six directions" in sentence
    assert "; for comparison, random start + post-optimization 21.2% / 8.8% per attempt; CVAE samples, raw 6.2% / 0.0% per attempt;" in sentence
    assert sentence.endswith("; optimization from scratch 55.0% / 50.0% per attempt.")
    assert sentence.count(".") == sentence.count("%") + 1  # one sentence: the only other full stops are decimal points
    no_six = _run_metrics().assign(six_dir_success_rate=np.nan)
    assert "(six-direction test not run)" in headline_sentence(headline_rows(no_six), {})
    # a row measured on fewer objects (the shipped model samples only objects it never trained on) says so
    shipped = _run_metrics().iloc[[2]].assign(method="shipped_post", n_objects=2, n_grasps=32, lift_success_rate=0.4)
    with_shipped = headline_sentence(headline_rows(pd.concat([_run_metrics(), shipped], ignore_index=True)), {})
    assert "shipped model's samples + post-optimization 40.0% / 13.8% per attempt (on 2 objects)" in with_shipped
    assert with_shipped.count("objects)") == 1


def test_measures_table_shows_percentages_with_intervals_and_readable_names():
    table = measures_table_html(headline_rows(_run_metrics()))
    assert table.count("<tr>") == 5  # header and four methods
    order = [table.index(method_label(m)) for m in ("cvae_post", "random_post", "cvae_raw", "optimization")]
    assert order == sorted(order)  # the product first, then its baselines
    assert "<b>17.5%</b> <small>(7–28)</small>" in table and "<b>13.8%</b> <small>(9–24)</small>" in table
    assert "0.175" not in table and "21 ms" in table and "80 on 5" in table
    without_six = measures_table_html(headline_rows(_run_metrics().assign(six_dir_success_rate=np.nan)))
    assert without_six.count("not run") == 4


def _with_ladder(frame: pd.DataFrame) -> pd.DataFrame:
    ladder = pd.DataFrame({
        "method": ["cvae_prior_train", "cvae_recon_post", "cvae_recon", "cvae_raw"], "split": ["train", "train", "train", "heldout"],
        "rung": ["in_distribution", "fit", "fit", "heldout"], "n_grasps": [40, 40, 40, 80], "n_objects": [10, 10, 10, 5],
        "lift_success_rate": [0.05, 0.3, 0.02, 0.0625], "six_dir_success_rate": [0.0, 0.2, 0.0, 0.0],
        "fit_rotation_error_deg_median": [np.nan, 20.0, 107.0, np.nan], "gap_to_training_mm": [3.0, np.nan, np.nan, np.nan],
    })  # fmt: skip
    return pd.concat([frame.assign(rung=np.nan), ladder], ignore_index=True)


def test_ladder_section_lists_rungs_in_order_and_only_when_measured():
    metrics = _with_ladder(_run_metrics())
    section = ladder_html(metrics)
    assert section.startswith("<h2>Learning ladder</h2>")
    positions = [section.index(method_label(m)) for m in ("cvae_recon", "cvae_recon_post", "cvae_prior_train")]
    assert positions == sorted(positions) and section.index("1 · fit") < section.index("2 · in distribution") < section.index("3 · held out")
    assert "palm rotation error (°, median)" in section and ">107<" in section  # the fit rung's own column, readable
    assert "gap to training mm" in section  # any other column only the ladder fills, by its name
    assert headline_rows(metrics)["method"].tolist() == ["cvae_post", "random_post", "cvae_raw", "optimization"]  # cvae_raw once
    assert ladder_html(_run_metrics()) == "" and ladder_html(_run_metrics().assign(rung=np.nan)) == ""


def test_page_order_first_screen_then_measures_ladder_plots_settings_csv():
    page = build_report_html(ReportInputs(metrics=_with_ladder(_run_metrics()), per_object=None, convergence=None, history=None,
                                          simulated=None, config={"seed": 3}, csv_links={"metrics.csv": "metrics.csv"}))  # fmt: skip
    marks = ["id='verdict'", "id='held-chart'", "id='summary-table'", "class='result'", "class='compact'", "<h2>Learning ladder</h2>",
             "<h2>Grasps, drawn at random", "<h2>Run settings</h2>", "href='metrics.csv'"]  # fmt: skip
    positions = [page.index(mark) for mark in marks]
    assert positions == sorted(positions)
    assert page.count("data:image/png") == 1  # one split: the first screen's chart is the success chart, not drawn twice
    assert "<h2>Success per method" not in page
    plain = build_report_html(ReportInputs(metrics=_run_metrics(), per_object=None, convergence=None, history=None, simulated=None))
    assert "Learning ladder" not in plain
    two_splits = pd.concat([_run_metrics(), _run_metrics().assign(split="train")], ignore_index=True)
    both = build_report_html(ReportInputs(metrics=two_splits, per_object=None, convergence=None, history=None, simulated=None))
    assert both.index("id='summary-table'") < both.index("<h2>Success per method, every split</h2>") and both.count("data:image/png") == 2


def test_training_steps_shown_are_the_steps_run():
    history = pd.DataFrame({"epoch": np.arange(1, 70), "step": np.arange(1, 70) * 20, "train_loss": np.linspace(2, 1, 69)})
    assert training_run_text(history) == "1,380 steps (69 epochs)"
    settings = run_settings_html({"train": {"epochs": 400, "max_steps": 2000}}, [], history)
    assert "<tr><td>training: steps run</td><td>1,380 steps (69 epochs)</td></tr>" in settings
    assert "training epochs" not in settings and training_run_text(None) is None


def _simulated(n_per_method: int) -> GraspSet:
    rng = np.random.default_rng(0)
    n = 2 * n_per_method
    lift = np.tile([True, False], n // 2)
    invalid = np.zeros(n, bool)
    invalid[1] = True  # a failure with no usable pose: never pictured
    return GraspSet({
        "hand_pose": grasp_poses(n, rng), "object_id": np.full(n, OBJECT_ID, dtype=object), "scale": np.full(n, 0.06, np.float32),
        "method": np.asarray(["cvae_post"] * n_per_method + ["optimization"] * n_per_method, dtype=object),
        "lift_success": lift, "invalid_reason": np.where(invalid, "non-finite hand_pose", "").astype(object),
    })  # fmt: skip


def test_pictured_grasps_are_drawn_at_random_with_a_seed():
    simulated = _simulated(40)
    picks = pick_examples(simulated, "cvae_post", 2, seed=0)
    assert picks == pick_examples(simulated, "cvae_post", 2, seed=0)  # reproducible
    assert [ok for _, ok in picks] == [True, True, False, False]
    assert all(bool(simulated.arrays["lift_success"][r]) == ok and r < 40 and r != 1 for r, ok in picks)
    drawn = {r for seed in range(30) for r, _ in pick_examples(simulated, "cvae_post", 2, seed=seed)}
    assert len(drawn) > 20  # not the first rows every time
    assert len(pick_examples(simulated, "optimization", 50, seed=0)) == 40  # no more than there are
    assert pick_examples(simulated, "cvae_post", 2, seed=1) != picks


def test_a_renamed_method_pictures_the_grasps_its_old_name_drew():
    """The optimization method's pictures are drawn with its frozen label "seed" (its name before the rename)."""
    simulated = _simulated(40)
    relabelled = GraspSet({**simulated.arrays, "method": np.where(simulated.arrays["method"] == "optimization", "seed", "cvae_post").astype(object)})
    for seed in range(5):
        assert pick_examples(simulated, "optimization", 2, seed=seed) == pick_examples(relabelled, "seed", 2, seed=seed)


def test_outcome_reads_both_tests():
    arrays = {
        "lift_success": np.array([True, True, False]),
        "six_dir_passed": np.array([[True] * 6, [True, True, True, False, False, False], [False] * 6]),
        "failure_reason": np.array(["", "", "object slipped"], dtype=object),
    }
    assert outcome_of(arrays, 0) == ("HELD", "held against 6 of 6 pushes", "held")
    assert outcome_of(arrays, 1) == ("LIFTED, FAILS PUSHES", "held against 3 of 6 pushes", "partial")  # e.g. a palm-up carry
    assert outcome_of(arrays, 2) == ("DROPPED", "held against 0 of 6 pushes · object slipped", "dropped")
    assert outcome_of({"lift_success": np.array([True])}, 0)[0] == "HELD"  # six-direction test not run: the lift decides


def test_picture_marks_the_contacts(tiny_objects):
    import io

    import matplotlib.image

    from dexlite_pipeline.hand import ShadowHand
    from dexlite_pipeline.report.pictures import contact_points, grasp_picture_png
    from dexlite_pipeline.report.render import object_mesh_world

    hand = ShadowHand()
    simulated = _simulated(2)
    object_mesh = object_mesh_world([str(tiny_objects)], OBJECT_ID, 0.06)
    nearest = contact_points(hand, simulated.hand_pose[0], None, object_mesh)
    given = contact_points(hand, simulated.hand_pose[0], np.array([0, 1, 2, 3]), object_mesh)
    assert nearest.shape == given.shape == (4, 3) and not np.allclose(nearest, given)
    image = matplotlib.image.imread(io.BytesIO(grasp_picture_png(hand, simulated, 0, [str(tiny_objects)], size_px=200)))
    red = (image[..., 0] > 0.8) & (image[..., 1] < 0.15) & (image[..., 2] < 0.15)
    assert red[:, :200].sum() > 20 and red[:, 200:].sum() > 20  # dots in both views


@pytest.mark.parametrize("column", ["rung"])
def test_metrics_without_or_with_empty_ladder_column_render(column):
    for frame in (_run_metrics(), _run_metrics().assign(**{column: ""})):
        page = build_report_html(ReportInputs(metrics=frame, per_object=None, convergence=None, history=None, simulated=None))
        assert "Learning ladder" not in page and "17.5%" in page


def test_lenient_test_column_only_when_measured():
    lenient = _run_metrics().assign(writeup_protocol_lift_success_rate=[0.7, 0.1, 0.4, 0.45], writeup_protocol_lift_success_ci95_low=0.3,
                                    writeup_protocol_lift_success_ci95_high=0.8)  # fmt: skip
    table = measures_table_html(headline_rows(lenient))
    assert "lift, the write-up's test" in table and "<td class='rate lenient'><b>40.0%</b> <small>(30–80)</small></td>" in table
    assert "the write-up's test" not in measures_table_html(headline_rows(_run_metrics()))
    assert "the write-up's test" not in measures_table_html(headline_rows(_run_metrics().assign(writeup_protocol_lift_success_rate=np.nan)))


def test_budget_plot_only_with_budget_rows():
    budget = pd.DataFrame({"method": ["cvae_post"] * 3 + ["random_post"] * 3, "iteration": [0, 100, 200] * 2,
                           "lift_success_rate": [0.05, 0.1, 0.2, 0.0, 0.1, 0.21], "lift_ci95_low": 0.0, "lift_ci95_high": 0.4})  # fmt: skip
    inputs = dict(metrics=_run_metrics(), per_object=None, convergence=None, history=None, simulated=None)
    with_budget = build_report_html(ReportInputs(**inputs, budget=budget))
    without = build_report_html(ReportInputs(**inputs))
    title = "<h2>Lift success against the post-optimization budget"
    assert title in with_budget and title not in without
    assert with_budget.count("data:image/png") == without.count("data:image/png") + 1


def test_learning_curve_section_only_with_a_curve():
    rows = []
    for point, objects in (("n10_seed0", 10), ("all", 600)):
        for method, rate in (("cvae_raw", 0.05), ("cvae_post", 0.2)):
            rows.append({"point": point, "seed": 0, "training_objects": objects, "training_grasps": 10 * objects, "method": method, "n_grasps": 768,
                         "lift_success_rate": rate, "lift_success_ci95_low": rate / 2, "lift_success_ci95_high": rate * 1.5,
                         "six_dir_success_rate": rate, "six_dir_success_ci95_low": rate / 2, "six_dir_success_ci95_high": rate * 1.5,
                         "seconds_per_grasp": 0.1})  # fmt: skip
    rows.append({**rows[0], "point": "random init", "training_objects": 0, "training_grasps": 0, "method": "random_post"})
    inputs = dict(metrics=_run_metrics(), per_object=None, convergence=None, history=None, simulated=None)
    with_curve = build_report_html(ReportInputs(**inputs, learning_curve=pd.DataFrame(rows)))
    without = build_report_html(ReportInputs(**inputs))
    title = "<h2>Learning curve of the shipped model's run</h2>"
    assert title in with_curve and title not in without
    assert with_curve.count("data:image/png") == without.count("data:image/png") + 1 and "n10_seed0" in with_curve


def _with_diversity(frame: pd.DataFrame) -> pd.DataFrame:
    return frame.assign(
        distinct_held_per_object_mean=2.5, surface_coverage_mean=0.31, energy_threshold_pass_rate=0.4, filtered_n_grasps=32,
        filtered_lift_success_rate=0.5, filtered_distinct_held_per_object_mean=1.2, filtered_surface_coverage_mean=0.2,
        cpu_seconds_per_distinct_held_grasp=5.2, filtered_cpu_seconds_per_distinct_held_grasp=np.inf,
    )  # fmt: skip


def test_diversity_beside_each_rate_per_attempt_and_after_the_filter():
    frame = _with_diversity(_run_metrics())
    table = measures_table_html(headline_rows(frame))
    assert table.count("<td class='diversity'>2.5</td><td class='diversity'>31.0%</td>") == 4  # beside the per-attempt rate
    assert table.count("<td class='diversity'>1.2</td><td class='diversity'>20.0%</td>") == 4  # beside the after-filter rate
    assert "<td>40.0% <small>(32)</small></td>" in table and "<b>50.0%</b>" in table and "5.2 s / ∞" in table
    sentence = headline_sentence(headline_rows(frame), {})
    assert ("against pushes from all six directions per attempt (2.5 distinct held grasps per object, 31.0% of the surface touched); "
            "after the energy filter every method goes through (40.0% of attempts pass), 50.0% held in the lift test "
            "(1.2 distinct held grasps per object, 20.0% of the surface touched); for comparison,") in sentence
    assert "random start + post-optimization 21.2% / 8.8% per attempt, 50.0% after the filter;" in sentence
    none_pass = frame.assign(filtered_n_grasps=0, filtered_lift_success_rate=np.nan, energy_threshold_pass_rate=0.0)
    assert measures_table_html(headline_rows(none_pass)).count("none pass") == 4
    assert "optimization from scratch 55.0% / 50.0% per attempt, none passing after the filter." in headline_sentence(headline_rows(none_pass), {})


def test_run_facts_below_the_first_screen(tmp_path):
    import datetime as dt
    import os

    from dexlite_pipeline.report.run_facts import run_facts

    benchmarks = tmp_path / "benchmarks"
    benchmarks.mkdir()
    for name, seconds, cpu, end in (("optimize_grasps_000.tsv", 10.0, 9.0, 1000.0), ("evaluate.tsv", 20.0, 18.0, 1100.0)):
        (benchmarks / name).write_text(f"s\th:m:s\tcpu_time\n{seconds}\t0:00:{int(seconds):02d}\t{cpu}\n")
        os.utime(benchmarks / name, (end, end))
    facts = dict(run_facts({"device": "cpu"}, benchmarks, checkout=tmp_path, now=dt.datetime(2026, 12, 2, 9, 30, tzinfo=dt.timezone.utc)))
    assert facts["report date"] == "2026-12-02 09:30 UTC"
    assert facts["code commit"] == "unknown"  # not a git checkout
    # the first job started at 1000 - 10 s, the last ended at 1100: 110 s
    assert facts["wall time of the run"] == "1.8 min from the first job's start to the last job's end (2 jobs: 30 s of job wall time, 27 s CPU)"
    assert "logical cores" in facts["machine"] and facts["machine"].endswith("torch device cpu")
    assert dict(run_facts({"device": "cpu"}, tmp_path / "absent"))["wall time of the run"].startswith("not measurable")
    page = build_report_html(ReportInputs(metrics=_run_metrics(), per_object=None, convergence=None, history=None, simulated=None,
                                          run_facts=list(facts.items())))  # fmt: skip
    # below the first screen, above every method's measures
    assert page.index("id='summary-table'") < page.index("<td>code commit</td><td>unknown</td>") < page.index("<p class='result'>")
