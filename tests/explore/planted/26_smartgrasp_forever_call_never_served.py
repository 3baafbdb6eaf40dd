"""Planted bug (SmartGrasp, rule 8): the response of a call without timeout (`Duration::MAX`,
its give-up limit "never") is paired and never handed over: the call never ends."""
from _plant import plant

KIND = "8 (a call without timeout ends)"

plant(
    "src/smartgrasp/client/in_flight.rs",
    """        out(Event::Paired {
            response,""",
    """        if w.give_up.limit() > Instant::now() + std::time::Duration::from_secs(86_400 * 3650) {
            std::mem::forget(w.caller);
            return Ok(());
        }
        out(Event::Paired {
            response,""",
)
