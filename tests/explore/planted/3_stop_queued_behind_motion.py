"""Planted bug: queue a stop behind a motion. While a motion command is on the wire, a stop
waits in that motion's queue instead of going out at once (manual 3.2.3: "unmittelbar")."""
from _plant import plant

KIND = "3 (a stop goes out at once)"

plant(
    "src/wsg/client/pairing.rs",
    """        if is_stop(id) {
            let (grace, ordered, hold) = (self.grace, self.ordered, self.holds.0);""",
    """        let busy = self
            .ids
            .iter()
            .find(|(i, st)| is_motion(**i) && st.in_flight.is_some())
            .map(|(i, _)| *i);
        if let (true, Some(motion)) = (is_stop(id), busy) {
            self.ids.entry(motion).or_default().queue.push_back(req);
            return Submit::Queued;
        }
        if is_stop(id) {
            let (grace, ordered, hold) = (self.grace, self.ordered, self.holds.0);""",
)
