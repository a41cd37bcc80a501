"""Model-agnostic estimation engine: sigma-point filters and smoothers, EKF, KF, RLS."""
