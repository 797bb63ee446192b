"""Evaluate contact detection against the simulator's ground truth.

Train a compensator on free motion, set the detector's thresholds from a held-out run's
residual, then run the contact scenario (free motion, the tool pressing on the table, leaving)
with the runtime chain in the loop and compare what it detected with the plant's contact
truth: detection delay, false positives, missed contacts, the contact wrench's error. The
command ``ftdrake evaluate-detection`` does the same on many seeds, surfaces and depths.

Run:  python examples/evaluate_detection.py
"""


import numpy as np

import ftdrake


def rehearsal(seed: int):
    """The task's motion stopping 3 cm above the table: contact-free data like the task."""
    return ftdrake.collect(ftdrake.ScenarioConfig(), 1, seed=seed, kind="rehearsal", n_jobs=1,
                           progress=False)


def main():
    train = rehearsal(seed=0)
    model = ftdrake.PhysicsPayloadCompensator(identify_mounting=True).fit(
        ftdrake.joint_state_layout(train), ftdrake.wrench_targets(train))

    held_out = rehearsal(seed=1)  # not trained on
    X_held = ftdrake.joint_state_layout(held_out)
    residual = ftdrake.wrench_targets(held_out) - model.predict(X_held)
    config = ftdrake.ScenarioConfig()  # the contact scenario: press on the table, leave
    # detector.test "auto", calibrated: the χ² test for a model with a std of a reading.
    test = config.chain.detector.for_model(model, calibrating=True).test
    detector = ftdrake.thresholds_for_false_positive_rate(  # the scenario's budget (1 per hour)
        residual, sample_rate_hz=config.sensor.spec().rate_hz, test=test,
        std=model.predict_std(X_held) if test == "chi2" else None)
    threshold = (f"χ² > {detector.chi2_on:.1f}" if detector.test == "chi2"
                 else f"{detector.force_on:.2f} N, {detector.torque_on:.3f} N·m")
    print(f"{detector.test} test, threshold from the held-out residual: {threshold}")

    config.trajectory.seed = config.sensor.seed = 7  # a seed not seen in training
    config = config.with_chain(detector=detector)
    result = ftdrake.simulate(ftdrake.build_station(config, model), progress=False)
    report = ftdrake.evaluate_detection(result.log, config.sensor.spec().noise_std)
    print(f"true contacts {report['true_contacts']}, detected {report['detected_contacts']}, "
          f"missed {report['missed_contacts']}, false positives {report['false_positives']}")
    delay_ms = 1e3 * np.atleast_1d(report["detection_delay_s"] or [])
    print(f"detection delay (ms): {np.round(delay_ms, 1)}")
    error = np.asarray(report["external_wrench_error_rms_after_touchdown"])
    print(f"contact wrench error after touchdown (RMS, N and N·m): {np.round(error, 3)}")
    print(f"free-motion compensation error / noise σ: "
          f"{np.round(report['compensation_error_over_noise'], 2)}")


if __name__ == "__main__":
    main()
