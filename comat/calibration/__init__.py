"""Calibration: short system-identification runs on the Robotarium, and the fit of the reality layer to their logs.

* :mod:`comat.calibration.schedule`: the experiments' command schedules (numpy only: shipped
  verbatim in the calibration export as ``calibration_schedule.py``);
* :mod:`comat.calibration.experiments`: the same experiments simulated under a known reality
  layer (:func:`simulate`), and the log format (:func:`load_log`);
* :mod:`comat.calibration.fit`: each experiment's fit (the layer's wheel model on the logged poses);
* :mod:`comat.calibration.from_runs`: the fit of a policy run's log (every run is also a calibration);
* :mod:`comat.calibration.profile`: every log fitted and combined into the table with intervals and
  the profile (:func:`fit_logs`, :func:`profile_fields`);
* :mod:`comat.calibration.intervals`: the kind of interval each parameter gets (over robots, over
  blocks of ticks for what the team shares, ...) and the check of a profile's intervals on reading;
* :mod:`comat.calibration.recovery`: the proof on known truth (simulate at a known layer, fit back, check);
* :mod:`comat.calibration.coverage`: whether the written intervals cover the truth, seed after seed.

A floor above :mod:`comat.control` and :mod:`comat.reality` (the layer it fits) and
:mod:`comat.measure` (its intervals); ``comat calibrate`` (:mod:`comat.cli.calibrate`) drives it.
"""
