"""Planted bug (rule 10): the replies of finger data (0x63, 0x73) are dropped as if nobody
waited for them, so `finger_data` is sent and answered but always ends in `Timeout`, at its
deadline: no other rule judges a kind of call that only ever times out."""
from _plant import plant

KIND = "10 (the quiet phase serves every kind of call"

plant(
    "src/wsg/client/task.rs",
    """                    if let Some(tx) = self.callers.remove(&token) {
                        if tx.send(Ok(reply)).is_err() {""",
    """                    if id == 0x63 || id == 0x73 {
                    } else if let Some(tx) = self.callers.remove(&token) {
                        if tx.send(Ok(reply)).is_err() {""",
)
