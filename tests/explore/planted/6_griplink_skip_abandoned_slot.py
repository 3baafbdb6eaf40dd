"""Planted bug (GRIPLINK): forget a command whose caller gave up. Its slot leaves the pipeline
before its reply came, so that reply answers the next caller's command (pairing by order,
manual 2.1, needs every sent command to keep its place until its reply)."""
from _plant import plant

KIND = "2 (the controller's answer"

plant(
    "src/griplink/client/pipeline.rs",
    """        let Some(slot) = self.slots.pop_front() else {""",
    """        while self.slots.len() > 1
            && self.slots.front().is_some_and(|s| s.caller.gave_up() && s.probe.is_none())
        {
            self.slots.pop_front();
        }
        let Some(slot) = self.slots.pop_front() else {""",
)
