"""Planted bug (WSG text, GCL; issue 29 rule 10): Client::pushes() (every push) subscribes with the
temperature's filter, so the stream of every push stays silent unless TEMP is pushed. The fault
phase reads pushes without requiring one; the quiet phase requires each kind of call to work."""
from _plant import plant

KIND = "10 (the quiet phase serves every kind of call)"

plant(
    "src/wsg/text/client.rs",
    """        self.subscribe(None)""",
    """        self.subscribe(Some(Quantity::Temperature))""",
)
