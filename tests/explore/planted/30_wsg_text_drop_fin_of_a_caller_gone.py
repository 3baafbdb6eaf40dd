"""Planted bug (WSG text, GCL; issue 29 rule 6): a FIN whose caller has gone (timed out, dropped)
is dropped without freeing its name, so the command stays on the wire until its give-up time and
the connection is declared lost although its reply came."""
from _plant import plant

KIND = "6 (a connection is lost only for cause)"

plant(
    "src/wsg/text/book.rs",
    """        let result = match (reply, slot.expect) {""",
    """        if matches!(reply, ReplyLine::Fin(_)) && slot.caller.as_ref().is_some_and(Caller::gave_up) {
            return Handled::Nothing;
        }
        let result = match (reply, slot.expect) {""",
)
