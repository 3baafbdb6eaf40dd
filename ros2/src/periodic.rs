//! The node's periodic work: something every period until shutdown.

use std::future::Future;
use std::time::Duration;

use tokio::sync::watch;

/// Runs `work` every `period` (the first at once; a late tick is skipped, not made up) until
/// `shutdown` turns true or its sender is gone.
pub async fn every<F, Fut>(period: Duration, mut shutdown: watch::Receiver<bool>, mut work: F)
where
    F: FnMut() -> Fut,
    Fut: Future<Output = ()>,
{
    let mut tick = tokio::time::interval(period);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    loop {
        tokio::select! {
            _ = tick.tick() => {}
            _ = shutdown.wait_for(|s| *s) => return,
        }
        work().await;
    }
}
