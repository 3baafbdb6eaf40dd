"""Planted bug: release a motion on one "not moving" probe (the pairing needs two, a grace
apart: SF_MOVING is not synchronised with the end of the move, Anhang B)."""
from _plant import plant

KIND = "2 (each answer is the device"

plant("src/wsg/client/pairing.rs", "Observation::Idle if f.idle_seen => {", "Observation::Idle => {")
