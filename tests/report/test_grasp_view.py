"""The interactive 3-D view: a self-contained HTML file that a real headless browser draws offline.

The browser test renders ``view.html`` in headless Chromium with every network request sent to a
closed port, takes a screenshot and checks that both the hand's and the object's colours are in
it. It skips only where Chromium is absent and cannot be installed (not root, or no apt-get);
``bash install.sh --test`` installs it as root.
"""

import re
import subprocess

import numpy as np
import pytest
from headless_chromium import offline_command
from image_colours import colour_fraction
from report_synthetic import OBJECT_ID, grasp_poses

from dexlite_pipeline.io.grasp_store import GraspSet
from dexlite_pipeline.report.grasp_view import (
    HAND_FACES,
    GraspViewError,
    ViewGrasp,
    decimated_hand_visual,
    grasp_label,
    grasp_view_html,
    spread_rows,
    write_grasp_set_view,
)
from dexlite_pipeline.report.render import HAND_RGB, OBJECT_RGB, hand_visual


def _screenshot(html_path, png_path, user_dir, size=(900, 700)) -> np.ndarray:
    """Headless Chromium's screenshot of ``html_path`` with no network (every request goes to a closed port)."""
    import matplotlib.image

    command = [*offline_command(user_dir, size, 20000), f"--screenshot={png_path}", html_path.as_uri()]
    subprocess.run(command, check=True, timeout=180, capture_output=True)
    return matplotlib.image.imread(png_path)


def _store(n: int) -> GraspSet:
    poses = grasp_poses(n, np.random.default_rng(0))
    passed = np.zeros((n, 6), bool)
    passed[:, :4] = True
    return GraspSet({
        "hand_pose": poses, "object_id": np.array([OBJECT_ID] * n, dtype=object), "scale": np.full(n, 0.06, np.float32),
        "lift_success": np.ones(n, bool), "lift_ratio": np.full(n, 0.97, np.float32), "six_dir_passed": passed,
        "E_fc": np.full(n, 0.25, np.float32), "E_dis": np.full(n, 0.004, np.float32), "penetration_mm": np.full(n, 1.5, np.float32),
    })


@pytest.mark.slow
def test_view_opens_offline_in_headless_chromium_with_hand_and_object(tmp_path, tiny_objects):
    view = write_grasp_set_view(tmp_path / "view.html", _store(3), [tiny_objects], title="box")
    html = view.read_text()
    assert not re.search(r"<script[^>]+src=", html)  # plotly.js is inline: nothing to fetch
    image = _screenshot(view, tmp_path / "shot.png", tmp_path / "chromium-profile")
    assert image.shape[:2] == (700, 900)
    assert colour_fraction(image, HAND_RGB) > 0.01, "the hand is not drawn"
    assert colour_fraction(image, OBJECT_RGB) > 0.01, "the object is not drawn"


def test_view_shows_one_grasp_at_a_time_with_its_results(tmp_path, tiny_objects):
    grasps = _store(2)
    html = write_grasp_set_view(tmp_path / "view.html", grasps, [tiny_objects]).read_text()
    label = grasp_label(grasps.arrays, 0)
    assert "held (lift ratio 0.97)" in label and "held 4/6 (+x −x +y −y)" in label
    assert "E_fc 0.25" in label and "E_dis 0.004 m" in label and "penetration 1.5 mm" in label
    assert html.count('"label":"1"') == 1 and html.count('"label":"2"') == 1  # a slider step per grasp
    assert '"visible":[true,true,false]' in html and '"visible":[true,false,true]' in html  # the object with one hand each


def test_view_of_a_failed_grasp_names_the_reason():
    arrays = {"object_id": np.array(["mug"]), "scale": np.array([0.1]), "lift_success": np.array([False]),
              "lift_ratio": np.array([np.nan]), "failure_reason": np.array(["initial penetration"], dtype=object)}
    assert grasp_label(arrays, 0) == "power grasp · mug (scale 0.100 m) · not held: initial penetration"  # no grasp_type: power
    # dexlite grasp's stores say which synthesis made each grasp, in place of the pipeline's method name
    sourced = {**arrays, "method": np.array(["optimization"], dtype=object), "source": np.array(["optimization"], dtype=object)}
    sourced["grasp_type"] = np.array(["pinch"], dtype=object)
    assert grasp_label(sourced, 0) == "from the optimization · pinch grasp · mug (scale 0.100 m) · not held: initial penetration"
    assert grasp_label({**arrays, "method": sourced["method"]}, 0).startswith("optimization · power grasp · mug")


def test_view_size_stays_small_per_grasp(tmp_path, tiny_objects):
    one = len(write_grasp_set_view(tmp_path / "one.html", _store(1), [tiny_objects]).read_bytes())
    nine = len(write_grasp_set_view(tmp_path / "nine.html", _store(9), [tiny_objects]).read_bytes())
    assert one < 6_000_000  # plotly.js (~4.7 MB) and one grasp
    assert (nine - one) / 8 < 80_000  # each further grasp: a decimated hand in binary arrays


def test_decimated_hand_keeps_every_link_and_about_the_face_budget():
    full, small = hand_visual(), decimated_hand_visual()
    assert 0.7 * HAND_FACES < len(small.faces) < 1.3 * HAND_FACES < len(full.faces)
    assert set(np.unique(small.vertex_link)) == set(np.unique(full.vertex_link))
    assert small.faces.max() < len(small.vertices)


def test_spread_rows_takes_grasps_from_every_object():
    ids = np.array(["a"] * 10 + ["b"] * 2 + ["c"] * 1)
    rows = spread_rows(ids, 6)
    assert sorted(set(ids[rows])) == ["a", "b", "c"] and len(rows) == 6
    assert list(spread_rows(ids, 100)) == list(range(13))


def test_view_refuses_no_grasp_or_a_missing_mesh():
    with pytest.raises(GraspViewError, match="no grasp"):
        grasp_view_html({}, [])
    with pytest.raises(GraspViewError, match="no mesh for object"):
        grasp_view_html({}, [ViewGrasp("mug", np.zeros(28), "")])


def test_report_embeds_the_view_of_its_pictured_grasps(tiny_objects):
    from dexlite_pipeline.report.inputs import ReportInputs
    from dexlite_pipeline.report.page import build_report_html

    grasps = _store(6)
    grasps.arrays["method"] = np.array(["cvae_raw"] * 3 + ["cvae_post"] * 3, dtype=object)
    grasps.arrays["lift_success"] = np.array([True, False, True, True, True, False])
    import pandas as pd

    page = build_report_html(ReportInputs(metrics=pd.DataFrame(), per_object=None, convergence=None, history=None, simulated=grasps,
                                          objects_dirs=[str(tiny_objects)], rendered_per_method=1))  # fmt: skip
    section = page[page.index("<h2>The same grasps in 3-D</h2>") :]
    assert section.index("class=\"plotly-graph-div\"") < section.index("<h2>", 5)
    assert page.index("<h2>Grasps, drawn at random") < page.index("<h2>The same grasps in 3-D</h2>")
    # one success and one failure per method, as in the pictures: four hands, each titled with its method
    steps = re.findall(r'"title.text":"4 grasps\\u003cbr\\u003e(\w+) ', section)
    assert section.count('"label":"') == 4 and sorted(steps) == ["cvae_post"] * 2 + ["cvae_raw"] * 2


def test_the_same_grasps_give_the_same_page(tmp_path, tiny_objects):
    """The view is deterministic: no random element ids, so a report or a dexlite grasp output repeats byte for byte."""
    first = write_grasp_set_view(tmp_path / "a.html", _store(2), [tiny_objects]).read_bytes()
    second = write_grasp_set_view(tmp_path / "b.html", _store(2), [tiny_objects]).read_bytes()
    assert first == second and b'id="grasp-view-' in first
