"""Planted bug: hand a stop reply to every waiting stop (issue 20 finding 3, fixed by
stops.rs): any stop reply completes every call waiting for one, even a call whose own stop was
sent after the stop that reply answers."""
from _plant import plant

KIND = "3 (stop Ok only if the device processed a stop"

plant("src/wsg/client/stops.rs", "let ends = w.first <= answered;", "let ends = w.first <= answered || true;")
