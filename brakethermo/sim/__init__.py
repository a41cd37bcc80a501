"""Truth models and session writers. Never imported by the estimator."""
