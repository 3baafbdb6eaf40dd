"""Planted bug: skip the late-reply discard. A request whose caller timed out gives its id up at
the caller's deadline, with no grace, so its late reply goes to the next caller of that id."""
from _plant import plant

KIND = "2 (each answer is the device"

plant("src/wsg/client/pairing/in_flight.rs", "release_at: after(req.deadline, grace),", "release_at: req.deadline,")
