"""Planted bug (rule 7): a call's deadline is half its timeout, so it fails with `Timeout` while
its reply may still arrive in time (promise 1 checks only that a call does not end late)."""
from _plant import plant

KIND = "7 (a Timeout only when its reply did not arrive in time"

plant(
    "src/wsg/client/mod.rs",
    """        let command = frame.id;
        let deadline = after(Instant::now(), timeout);""",
    """        let command = frame.id;
        let deadline = after(Instant::now(), timeout / 2);""",
)
