"""Planted bug: release a motion on one "not moving" probe (the pairing needs two, a grace
apart: SF_MOVING is not synchronised with the end of the move, Anhang B). Its caller gets
ReplyLost while the final reply is still coming: promise 4's ReplyLost check (TCP, serial)."""
from _plant import plant

KIND = "4 (ReplyLost only for a final reply that was lost"

plant(
    "src/wsg/client/pairing.rs",
    "(Observation::Idle, Some(first)) if now >= after(first, grace) => {",
    "(Observation::Idle, _) => {",
)
