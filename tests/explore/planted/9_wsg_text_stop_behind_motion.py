"""Planted bug (WSG text, GCL): queue STOP() behind a motion. While a motion waits for its
`FIN`, a STOP waits in the client until a name is freed, instead of going out at once (the
gripper reads STOP during motion, shared note §3.7)."""
from _plant import plant

KIND = "3 (a stop goes out at once)"

plant(
    "src/wsg/text/book.rs",
    """        if self.on_wire.contains_key(request.name) {""",
    """        let motion = self.on_wire.values().any(|s| s.expect == Expect::Fin);
        if self.on_wire.contains_key(request.name) || (request.name == "STOP" && motion) {""",
)
plant(
    "src/wsg/text/task.rs",
    """                        Handled::Freed(name) => to_send = next_waiting(&mut book, name),""",
    """                        Handled::Freed(name) => {
                            to_send = next_waiting(&mut book, name)
                                .or_else(|| next_waiting(&mut book, "STOP"))
                        }""",
)
