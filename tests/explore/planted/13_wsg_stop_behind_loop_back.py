"""Planted bug (rule 9): a stop waits behind a loop-back on the wire (a barrier, or a caller's)
instead of going out at once (manual 3.2.3: "unmittelbar"); issue 29 E is of this kind."""
from _plant import plant

KIND = "9 (a stop is sent at once"

plant(
    "src/wsg/client/pairing.rs",
    """        if is_stop(id) {
            let (grace, ordered, hold) = (self.grace, self.ordered, self.holds.0);""",
    """        let loop_busy = self
            .ids
            .get(&crate::wsg::command::id::LOOP)
            .is_some_and(|st| st.in_flight.is_some());
        if is_stop(id) && loop_busy {
            let st = self.ids.entry(crate::wsg::command::id::LOOP).or_default();
            st.queue.push_back(req);
            return Submit::Queued;
        }
        if is_stop(id) {
            let (grace, ordered, hold) = (self.grace, self.ordered, self.holds.0);""",
)
