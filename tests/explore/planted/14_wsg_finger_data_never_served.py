"""Planted bug (rule 10): the replies of finger data (0x63, 0x73) are dropped as if nobody
waited for them, so `finger_data` is sent and answered but always ends in `Timeout`, at its
deadline: no other rule judges a kind of call that only ever times out."""
from _plant import plant

KIND = "10 (the quiet phase serves every kind of call"

plant(
    "src/wsg/client/task.rs",
    """                Output::Reply(token, reply) => {""",
    """                Output::Reply(_, ref r) if r.id == 0x63 || r.id == 0x73 => {}
                Output::Reply(token, reply) => {""",
)
