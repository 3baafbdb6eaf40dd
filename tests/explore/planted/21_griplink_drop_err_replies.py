"""Planted bug (GRIPLINK, rule 7): an `ERR` reply is consumed and never handed to its caller
(a decoder that drops good lines), who then waits out its timeout although its reply reached
the client intact."""
from _plant import plant

KIND = "7 (a Timeout only when its reply did not arrive in time)"

plant(
    "src/griplink/client/pipeline.rs",
    "            _ if slot.caller.gave_up() => {",
    """            Err(Error::Device { .. }) => {
                std::mem::forget(slot.caller);
                Delivery::Discarded
            }
            _ if slot.caller.gave_up() => {""",
)
