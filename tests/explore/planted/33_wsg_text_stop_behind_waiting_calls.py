"""Planted bug (WSG text, GCL; issue 29 rule 9): STOP() takes its turn behind the requests waiting
for busy names (first come, first served) instead of going out at once. The quiet phase's live
stop check (rule 3) cannot see it: nothing waits there."""
from _plant import plant

KIND = "9 (a stop is sent at once, faults or not)"

plant(
    "src/wsg/text/book.rs",
    """        if self.on_wire.contains_key(request.name) {""",
    """        let behind = request.name == "STOP" && !self.waiting.is_empty();
        if self.on_wire.contains_key(request.name) || behind {""",
)
plant(
    "src/wsg/text/task.rs",
    """                        Handled::Freed(name) => to_send = next_waiting(&mut book, name),""",
    """                        Handled::Freed(name) => {
                            to_send = next_waiting(&mut book, name)
                                .or_else(|| next_waiting(&mut book, "STOP"))
                        }""",
)
