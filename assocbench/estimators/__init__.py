"""Estimators: the closed loop's belief. Each frame: ``predict(motion)``, ``problem(frame)``,
``update(association)``, then (SLAM) ``initialise(frame, features)``. See ``base.Estimator``."""
