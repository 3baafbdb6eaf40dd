"""Planted bug (GRIPLINK): accept a reply without the shape check. A reply is read as the
answer to the oldest command whatever its key, so after a dropped reply `ID?` can return the
`LABEL=...` of the next command."""
from _plant import plant

KIND = "2 (the controller's answer"

plant(
    "src/griplink/client/pipeline.rs",
    "Ok(text) => interpret_datum(&slot.line, slot.expect, text),",
    "Ok(text) => interpret_datum(&slot.line, Expect::Any, text),",
)
