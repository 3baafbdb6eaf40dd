"""Planted bug (SmartGrasp, rule 6): a response is given up on at its call's deadline, without
`ClientConfig::give_up_after`: a server that answers a little late, in order, gets its healthy
connection declared lost."""
from _plant import plant

KIND = "6 (a connection is lost only for cause)"

plant(
    "src/smartgrasp/client/in_flight.rs",
    """            deadline,
            self.give_up_after,""",
    """            deadline,
            std::time::Duration::ZERO,""",
)
