"""Planted bug (SmartGrasp): pair responses by arrival alone. The response is handed to the
oldest waiting request without the checks of its message type and echoed fields
(`check_response`), so after a dropped response a call can return the next request's answer."""
from _plant import plant

KIND = "2 (the server's answer"

plant(
    "src/smartgrasp/client/in_flight.rs",
    "if let Err(e) = check_response(&w.request, frame) {",
    "if let Err(e) = std::result::Result::<(), Malformed>::Ok(()) {",
)
