"""Planted bug (GRIPLINK, rule 6): a reply is given up on at its call's deadline, without the
`give_up_after` the client docs promise ("If a reply stays away give_up_after beyond its call's
timeout"): a controller that answers a little late, in order, gets its healthy connection
declared lost."""
from _plant import plant

KIND = "6 (a connection is lost only for cause)"

plant(
    "src/griplink/client/pipeline.rs",
    """GiveUp::new(deadline, self.give_up_after, self.slots.is_empty(), || {""",
    """GiveUp::new(deadline, Duration::ZERO, self.slots.is_empty(), || {""",
)
