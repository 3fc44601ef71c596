"""Reference, PID, feedforward, estimators, clocks and the tick loop."""
