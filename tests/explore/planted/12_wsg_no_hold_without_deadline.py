"""Planted bug (rule 8): the holds that bound a request whose caller has no timeout
(`Duration::MAX`) are never set, so such a request whose reply is lost keeps its id, and its
caller waits, for ever (issue 20's finding, `Pairing::set_holds`)."""
from _plant import plant

KIND = "8 (a call without timeout ends"

plant(
    "src/wsg/client/pairing.rs",
    "self.holds = (reply, motion);",
    "let _ = (reply, motion);",
)
