"""Planted bug (SmartGrasp, rule 7): a GRASP_FEEDBACK response is paired and then never handed
to its caller (a decoder that drops good frames), who waits out its timeout although the
response reached the client intact."""
from _plant import plant

KIND = "7 (a Timeout only when its reply did not arrive in time)"

plant(
    "src/smartgrasp/client/in_flight.rs",
    """        out(Event::Paired {
            response,""",
    """        if response.header().message_type == MessageType::GraspFeedback {
            std::mem::forget(w.caller);
            return Ok(());
        }
        out(Event::Paired {
            response,""",
)
