"""Planted bug (WSG text, GCL): pair a FIN by arrival, not by command name. A `FIN` line
completes whichever motion waits for one (the first the map yields), so with a HOME still on the
wire after its caller timed out, a later MOVE can return Ok on `FIN HOME`."""
from _plant import plant

KIND = "2 (the device's answer to that request)"

plant(
    "src/wsg/text/book.rs",
    """        let Some((&key, slot)) = self
            .on_wire
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(name))""",
    """        let fin = matches!(reply, ReplyLine::Fin(_))
            && self.on_wire.values().any(|s| s.expect == Expect::Fin);
        let Some((&key, slot)) = self
            .on_wire
            .iter()
            .find(|(k, s)| if fin { s.expect == Expect::Fin } else { k.eq_ignore_ascii_case(name) })""",
)
