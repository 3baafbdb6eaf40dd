"""Planted bug (WSG text, GCL; issue 29 rule 8): a call without timeout (Duration::MAX) that had
to wait behind a busy name is never taken from the waiting queue (the next request of a freed
name is looked for among the ones with a deadline only): it waits for ever."""
from _plant import plant

KIND = "8 (a call without timeout ends, and frees what it held)"

plant(
    "src/wsg/text/book.rs",
    """            let i = self.waiting.iter().position(|r| r.name == name)?;""",
    """            let i = self
                .waiting
                .iter()
                .position(|r| r.name == name && r.timeout != Duration::MAX)?;""",
)
