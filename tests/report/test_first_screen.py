"""The report's first screen: the verdict (at most 40 words, from the run's numbers), the held-per-attempt chart and the
summary table, and, in headless Chromium at 1280 × 900, all three within the first screen with no sideways overflow."""

import html.parser
import itertools
import subprocess

import numpy as np
import pandas as pd
import pytest
from headless_chromium import offline_command

from dexlite_pipeline.report.first_screen import (
    GENERATING_METHODS,
    VERDICT_WORDS,
    first_screen_html,
    first_screen_rows,
    ratio_text,
    recommended_method,
    summary_table_html,
    verdict_sentence,
    word_count,
)
from dexlite_pipeline.report.inputs import ReportInputs
from dexlite_pipeline.report.page import build_report_html
from dexlite_pipeline.report.tables import HEADLINE_METHODS

SCREEN = (1280, 900)


def _row(method: str, lift: float, distinct: float = 2.0, cpu: float = 10.0, split: str = "heldout", objects: int = 20) -> dict:
    """One metrics.csv row: the lift rate with an object-bootstrap interval of ±0.07, six directions at 70% of it."""
    return {
        "method": method, "split": split, "n_grasps": 16 * objects, "n_invalid": 0, "n_objects": objects, "lift_success_rate": lift,
        "lift_success_boot_ci95_low": max(lift - 0.07, 0.0), "lift_success_boot_ci95_high": min(lift + 0.07, 1.0),
        "lift_success_ci95_low": max(lift - 0.05, 0.0), "lift_success_ci95_high": min(lift + 0.05, 1.0), "object_success_rate": 0.9,
        "six_dir_success_rate": 0.7 * lift, "six_dir_success_boot_ci95_low": 0.6 * lift, "six_dir_success_boot_ci95_high": 0.8 * lift,
        "distinct_held_per_object_mean": distinct, "surface_coverage_mean": 0.3, "held_start_depth_median_mm": 2.4,
        "cpu_seconds_per_distinct_held_grasp": cpu, "seconds_per_grasp": 0.5,
    }  # fmt: skip


def _metrics() -> pd.DataFrame:
    """The ranked model wins: 42% against optimization from scratch's 30%, more distinct grasps, a quarter of the CPU."""
    return pd.DataFrame([
        _row("cvae_post", 0.35, distinct=2.8, cpu=3.0), _row("cvae_ranked_post", 0.42, distinct=3.2, cpu=2.5),
        _row("cvae_raw", 0.05, distinct=0.6, cpu=0.4), _row("optimization", 0.30, distinct=2.1, cpu=10.0),
    ])  # fmt: skip


def test_verdict_names_the_best_method_against_optimization_from_scratch():
    sentence = verdict_sentence(first_screen_rows(_metrics()))
    assert sentence == (
        "Recommended on 20 held-out objects: post-optimized ranked CVAE samples, 42.0% held per attempt (95% CI 35–49%) "
        "vs 30.0% (23–37%) for optimization from scratch. Distinct held grasps per object: 3.2 vs 2.1, at 0.25× the CPU-seconds "
        "per distinct held grasp."
    )
    assert word_count(sentence) <= VERDICT_WORDS
    # read from the numbers: another winner, other rates, another ratio
    other = pd.DataFrame([_row("cvae_post", 0.5, distinct=2.8, cpu=3.0), _row("cvae_ranked_post", 0.42), _row("optimization", 0.3, distinct=2.1)])
    changed = verdict_sentence(first_screen_rows(other))
    assert "post-optimized CVAE samples, 50.0% held per attempt (95% CI 43–57%)" in changed and "2.8 vs 2.1, at 0.3× the CPU" in changed


def test_verdict_without_optimization_from_scratch_compares_with_the_runner_up():
    sentence = verdict_sentence(first_screen_rows(_metrics().query("method != 'optimization'")))
    assert "optimization from scratch" not in sentence
    assert "42.0% held per attempt (95% CI 35–49%) vs 35.0% (28–42%) for post-optimized CVAE samples." in sentence
    assert "3.2 vs 2.8, at 0.83× the CPU-seconds" in sentence and word_count(sentence) <= VERDICT_WORDS


def test_verdict_says_nothing_about_cpu_without_cpu_numbers():
    for frame in (_metrics().drop(columns="cpu_seconds_per_distinct_held_grasp"), _metrics().assign(cpu_seconds_per_distinct_held_grasp=np.nan)):
        sentence = verdict_sentence(first_screen_rows(frame))
        assert "CPU" not in sentence and sentence.endswith("Distinct held grasps per object: 3.2 vs 2.1.")
    table = summary_table_html(first_screen_rows(_metrics().drop(columns="cpu_seconds_per_distinct_held_grasp")))
    assert "CPU" not in table and table.count("</th>") == 5


def test_verdict_when_scratch_is_best_or_alone_or_nothing_held():
    scratch_best = verdict_sentence(first_screen_rows(pd.DataFrame([_row("cvae_ranked_post", 0.42, distinct=3.2, cpu=2.5),
                                                                    _row("optimization", 0.6, distinct=2.1, cpu=10.0)])))
    assert scratch_best.startswith("Recommended on 20 held-out objects: optimization from scratch, 60.0% held per attempt")
    assert "vs 42.0% (35–49%) for post-optimized ranked CVAE samples." in scratch_best and "2.1 vs 3.2, at 4× the CPU" in scratch_best
    alone = verdict_sentence(first_screen_rows(_metrics().query("method == 'cvae_post'")))
    assert alone == ("Recommended on 20 held-out objects: post-optimized CVAE samples, the only way of making grasps evaluated, "
                     "35.0% held per attempt (95% CI 28–42%). Distinct held grasps per object: 2.8.")  # fmt: skip
    nothing = verdict_sentence(first_screen_rows(_metrics().assign(lift_success_rate=0.0)))
    assert nothing == "No way of making grasps held an object in the lift test on 20 held-out objects (4 evaluated)."
    assert verdict_sentence(first_screen_rows(pd.DataFrame())) == "No way of making grasps was lift-tested in this run."


def test_imported_grasps_are_not_recommended_and_training_rows_not_on_the_first_screen():
    frame = pd.concat([_metrics(), pd.DataFrame([_row("dexgraspnet", 0.9), _row("cvae_ranked_post", 0.8, split="train")])], ignore_index=True)
    rows = first_screen_rows(frame)
    assert set(rows["split"]) == {"heldout"} and recommended_method(rows) == "cvae_ranked_post"
    assert "42.0% held" in verdict_sentence(rows)


def test_verdict_fits_its_words_for_every_pair_of_methods():
    """Longest names and numbers: every best and reference method, with 100.0%, a three-digit ratio and two-digit counts."""
    for best, reference in itertools.permutations(GENERATING_METHODS, 2):
        frame = pd.DataFrame([_row(best, 1.0, distinct=12.5, cpu=0.0123), _row(reference, 0.999, distinct=10.25, cpu=123.0)])
        sentence = verdict_sentence(first_screen_rows(frame))
        assert word_count(sentence) <= VERDICT_WORDS and "CPU-seconds" in sentence, sentence


def test_cpu_ratio_text():
    assert [ratio_text(r) for r in (0.25, 4.0, 0.8333, 1234.5, 0.000123)] == ["0.25×", "4×", "0.83×", "1234×", "0.00012×"]


def test_summary_table_has_at_most_seven_columns_and_marks_the_recommendation():
    table = summary_table_html(first_screen_rows(_metrics()), "cvae_ranked_post")
    assert table.count("</th>") == 6 <= 7
    assert "<b>42.0%</b> <small>(35–49)</small>" in table and ">2.4<" in table and ">2.5 s<" in table
    assert table.count("class='best'") == 1 and "recommended" in table
    block = first_screen_html(_metrics())
    assert block.index("id='verdict'") < block.index("id='held-chart'") < block.index("id='summary-table'") and "data:image/png" in block


# Measures the first screen once the page (and its images) has loaded, into data-* attributes of <body>.
PROBE = """<script>
window.addEventListener('load', function () {
  function box(el) { if (!el) return 'missing'; var r = el.getBoundingClientRect();
    return [r.left, r.top, r.right, r.bottom].map(Math.round).join(' '); }
  var table = document.getElementById('summary-table'), wide = document.querySelector('div.wide');
  var b = document.body.dataset;
  b.viewport = window.innerWidth + ' ' + window.innerHeight;
  b.verdict = box(document.getElementById('verdict'));
  b.chart = box(document.querySelector('#held-chart img'));
  b.table = box(table);
  b.tableHolder = box(table && table.parentElement);
  b.tableOverflow = table ? (table.scrollWidth - table.clientWidth) + ' ' + (table.parentElement.scrollWidth - table.parentElement.clientWidth) : 'missing';
  b.pageWidth = document.documentElement.scrollWidth;
  b.wideOverflow = wide ? wide.scrollWidth - wide.clientWidth : 'missing';
});
</script>"""


class _BodyAttributes(html.parser.HTMLParser):
    def __init__(self):
        super().__init__()
        self.attributes = {}

    def handle_starttag(self, tag, attrs):
        if tag == "body":
            self.attributes = dict(attrs)


def _measured(page: str, tmp_path) -> dict[str, str]:
    """The probe's measurements of ``page`` in headless Chromium at 1280 × 900 (its --dump-dom of <body>'s data-* attributes)."""
    path = tmp_path / "report.html"
    path.write_text(page.replace("</body>", PROBE + "</body>"))
    command = [*offline_command(tmp_path / "chromium-profile", SCREEN, 5000), "--dump-dom", path.as_uri()]
    dom = subprocess.run(command, check=True, timeout=120, capture_output=True, text=True).stdout
    parser = _BodyAttributes()
    parser.feed(dom)
    return {k.removeprefix("data-"): v for k, v in parser.attributes.items() if k.startswith("data-")}


def _worst_case_metrics() -> pd.DataFrame:
    """Every main method on the held-out objects (the tallest table and chart), with the write-up's lenient test, a training
    split and the learning ladder's rows (a wide table below the first screen)."""
    rows = [_row(m, 0.05 + 0.1 * k, distinct=3.25, cpu=12.5 + k) for k, m in enumerate(HEADLINE_METHODS)]
    rows.append(_row("cvae_post", 0.6, split="train"))
    rows += [{**_row(m, 0.3, split="train"), "rung": rung, "fit_rotation_error_deg_median": 20.0, "fit_translation_error_mm_median": 3.0}
             for m, rung in (("cvae_recon", "fit"), ("cvae_recon_post", "fit"), ("cvae_prior_train", "in_distribution"))]  # fmt: skip
    return pd.DataFrame(rows).assign(writeup_protocol_lift_success_rate=0.6, writeup_protocol_lift_success_ci95_low=0.5,
                                     writeup_protocol_lift_success_ci95_high=0.7, energy_threshold_pass_rate=0.4, filtered_n_grasps=100,
                                     filtered_lift_success_rate=0.5)  # fmt: skip


@pytest.mark.parametrize("metrics", [_metrics(), _worst_case_metrics()], ids=["four methods", "every method"])
def test_first_screen_fits_1280_by_900_in_headless_chromium(metrics, tmp_path):
    facts = [("report date", "2026-12-02 09:30 UTC"), ("code commit", "v1.0"), ("wall time of the run", "3.2 h"), ("machine", "2 logical cores")]
    history = pd.DataFrame({"step": np.arange(20), "train_loss": np.linspace(2, 1, 20), "val_loss": np.linspace(2.1, 1.1, 20)})
    loop = pd.DataFrame({"round": [0, 1], "grasps_per_object": [10.0, 14.5], "distinct_per_object": [6.0, 8.25], "distinct_min": [1, 2],
                         "objects_without_grasps": [3, 1], "kept": [0, 812], "sampled": [0, 4096], "cpu_seconds": [3600.0, 5400.0],
                         "heldout_lift_success": [0.2, 0.25], "heldout_six_dir_success": [0.1, 0.15], "heldout_distinct_per_object": [1.5, 2.0],
                         "not_optimized": [0, 12], "energy_filter": [0, 900], "lift_test": [0, 1400], "six_directions": [0, 700], "duplicate": [0, 272]})
    page = build_report_html(ReportInputs(metrics=metrics, per_object=None, convergence=None, history=history, simulated=None,
                                          run_facts=facts, config={"seed": 3}, data_loop=loop))  # fmt: skip
    found = _measured(page, tmp_path)
    width, height = SCREEN
    assert found.get("viewport", "").split()[0] == str(width), found  # the page is laid out 1280 px wide (its height: less the window's frame)
    for name in ("verdict", "chart", "table"):
        left, top, right, bottom = map(int, found[name].split())
        assert 0 <= left < right <= width and 0 <= top < bottom <= height, f"{name} {found[name]} is not within the first {width} × {height} screen"
    chart_left, chart_top, chart_right, chart_bottom = map(int, found["chart"].split())
    assert chart_bottom - chart_top > 200 and chart_right - chart_left > 300  # the picture was drawn, not an empty box
    assert found["table-overflow"] == "0 0", "the summary table overflows sideways"
    assert int(found["table"].split()[2]) <= int(found["table-holder"].split()[2])
    assert int(found["page-width"]) <= width, "something on the page is wider than the screen"
    assert int(found["wide-overflow"]) > 0  # the probe does see overflow: the wide table below scrolls in its own box
