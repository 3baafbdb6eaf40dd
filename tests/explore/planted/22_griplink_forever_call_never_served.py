"""Planted bug (GRIPLINK, rule 8): the reply of a call without timeout (`Duration::MAX`, its
give-up limit "never") is taken for an abandoned call's and consumed: the call never ends."""
from _plant import plant

KIND = "8 (a call without timeout ends)"

plant(
    "src/griplink/client/pipeline.rs",
    "            _ if slot.caller.gave_up() => {",
    """            _ if slot.give_up.limit() > Instant::now() + Duration::from_secs(86_400 * 3650) => {
                std::mem::forget(slot.caller);
                Delivery::Discarded
            }
            _ if slot.caller.gave_up() => {""",
)
