"""Planted bug (SmartGrasp, rule 10): `get_object_count` reads only a count of all classes
(echoed class 0); a count of one class fails as an unexpected body, while every other kind of
call works (the old quiet phase, one GET_STATE, passed)."""
from _plant import plant

KIND = "10 (the quiet phase serves every kind of call)"

plant(
    "src/smartgrasp/client/mod.rs",
    "ResponseBody::ObjectCount(c) => Ok(ObjectCount { object_class, ..c }),",
    "ResponseBody::ObjectCount(c) if c.object_class == 0 => Ok(ObjectCount { object_class, ..c }),",
)
