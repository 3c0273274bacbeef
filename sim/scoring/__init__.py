"""Scoring the rover's downlink against the simulator's truth: the truth record
(``truth.Truth``) and the scorer that makes it (``scorer.Scorer``)."""
