"""The main job (tools/scenes/hanging_square.toml and its script, touch_stroke_pinch.toml) on the
stepped clock, as `tools/run` plays it: its 23-32 mm elements are refined under the fingertips by
default (haptics.refine = "auto" with direct coupling), and the refinement gives the user no
energy: the passivity controller never acts over the touch, the stroke and the pinch."""
import json
import subprocess
from pathlib import Path

from buildpaths import build_dir

REPO = Path(__file__).resolve().parents[2]
SCENE = REPO / "tools" / "scenes" / "hanging_square.toml"


def test_the_main_job_refines_under_the_fingertips_and_stays_passive(tmp_path):
    r = subprocess.run([str(build_dir() / "hapticloth-server"), "--scene", str(SCENE), "--fast",
                        "--json", "--no-zenoh", "--no-lcm-log"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    s = json.loads(r.stdout)
    assert any('local refinement on (haptics.refine = "auto")' in line for line in s["stages"]), s["stages"]
    assert s["refinement_builds"] > 0 and s["refinement_updates"] > 0
    # The coupling's energy balance: below the controller's 1 uJ deadband on every tick.
    assert s["passivity_ticks"] == 0 and s["passivity_deficit_j"] < 1e-6, (s["passivity_ticks"],
                                                                             s["passivity_deficit_j"])
    # The script's press, stroke and pinch stay within the device's range (the pinch's largest
    # force is 1.5 N with and without refinement).
    assert 0.5 < s["max_force_n"] < 2.0
