"""Planted bug (rule 6): a reply nobody waits for (a late or duplicated reply, an update of a
value nobody streams any more) is taken for a broken link, and the healthy connection is
declared lost (`ConnectionLost`), though the device answers in order."""
from _plant import plant

KIND = "6 (a connection is lost only for cause"

plant(
    "src/wsg/client/task.rs",
    """tracing::debug!(id = reply.id, status = %reply.status,
                            "WSG reply nobody waits for: dropped");""",
    """return Err(io::Error::other("a reply nobody waits for"));""",
)
