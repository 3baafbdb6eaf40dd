"""Planted bug (rule 10): `finger_data` is sent with no time to answer (a zero timeout), so it
never succeeds, faults or not; no other rule looks at a kind of call that only times out."""
from _plant import plant

KIND = "10 (the quiet phase serves every kind of call"

plant(
    "src/wsg/client/commands.rs",
    """        self.command(Command::FingerData(finger)).await""",
    """        self.with_timeouts(std::time::Duration::ZERO, std::time::Duration::ZERO)
            .command(Command::FingerData(finger))
            .await""",
)
