"""Planted bug (WSG text, GCL; issue 29 rule 7): a value without a decimal point (GRIPSTATE=4,
VERBOSE=1, PWT=5) is taken for a line cut short and dropped: its call times out although its
reply was read in time (a decoder that silently drops good lines)."""
from _plant import plant

KIND = "7 (a Timeout only when its reply did not arrive in time)"

plant(
    "src/wsg/text/book.rs",
    """            (ReplyLine::Value { value, .. }, Expect::Value) => {""",
    """            (ReplyLine::Value { value, .. }, Expect::Value) if !value.contains('.') => {
                return Handled::Nothing
            }
            (ReplyLine::Value { value, .. }, Expect::Value) => {""",
)
