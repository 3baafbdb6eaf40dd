"""Planted bug (GRIPLINK, rule 10): a recipe reply (`GRIPCFG`, manual 3.6.1: a tag and eight
parameters, nine items) is read as eight items: every recipe read fails, while every other kind
of call works (the old quiet phase, one `ID?`, passed)."""
from _plant import plant

KIND = "10 (the quiet phase serves every kind of call)"

plant(
    "src/griplink/client/mod.rs",
    "Value::List(items) if items.len() == 9 => match items.split_first() {",
    "Value::List(items) if items.len() == 8 => match items.split_first() {",
)
