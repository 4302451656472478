"""benchmarks/experiments/lift_cost.py: its step clock counts MuJoCo's steps and fingerprints the trajectory, and its
digests tell outcomes apart."""

import numpy as np

BOX = """<mujoco><worldbody><geom type="plane" size="1 1 0.1"/>
<body pos="0 0 0.3"><freejoint/><geom type="box" size="0.05 0.05 0.05"/></body></worldbody></mujoco>"""


def _fall(clock_type, chunks=(10, 10, 5)) -> object:
    import mujoco

    model = mujoco.MjModel.from_xml_string(BOX)
    data = mujoco.MjData(model)
    with clock_type() as clock:
        for steps in chunks:
            mujoco.mj_step(model, data, nstep=steps)
    return clock


def test_step_clock_counts_steps_hashes_states_and_puts_mj_step_back(benchmark_script):
    import mujoco

    script = benchmark_script("lift_cost")
    step = mujoco.mj_step
    first, again = _fall(script.StepClock), _fall(script.StepClock)
    assert mujoco.mj_step is step
    assert (first.steps, first.calls) == (25, 3) and first.seconds >= 0.0
    assert first.trajectory == again.trajectory
    assert _fall(script.StepClock, (10, 10, 6)).trajectory != first.trajectory


def test_digests_change_with_a_flag_or_a_value(benchmark_script):
    script = benchmark_script("lift_cost")
    results = {"lift_success": np.array([True, False]), "failure_reason": np.array(["", "dropped"], dtype=object),
               "lift_ratio": np.array([0.99, 0.1], np.float32)}
    flags = ("lift_success", "failure_reason")
    base = script.digest(results, flags), script.digest(results, flags + ("lift_ratio",))
    results["lift_ratio"][1] = np.nextafter(np.float32(0.1), np.float32(1.0))
    assert script.digest(results, flags) == base[0] and script.digest(results, flags + ("lift_ratio",)) != base[1]
    results["failure_reason"][1] = "simulation_unstable"
    assert script.digest(results, flags) != base[0]


def test_phase_clock_counts_inside_its_block_and_puts_every_function_back(benchmark_script):
    import mujoco

    from dexlite_pipeline.energy.grasp_energy import GraspEnergy
    from dexlite_pipeline.sim.simulator import GraspSimulator

    script = benchmark_script("lift_cost")
    originals = mujoco.mj_step, vars(GraspEnergy)["from_assets"], vars(GraspSimulator)["lift"]
    clock = _fall(script.PhaseClock)
    assert clock.calls["mj_step (the physics)"] == 3 and clock.seconds["mj_step (the physics)"] >= 0.0
    assert (mujoco.mj_step, vars(GraspEnergy)["from_assets"], vars(GraspSimulator)["lift"]) == originals
    assert "| mj_step (the physics) |" in clock.table(1.0, 1)
