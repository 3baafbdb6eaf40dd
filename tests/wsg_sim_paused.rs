//! The simulator under tokio's paused clock (as the explorer runs it, issue 20): auto-updates
//! and motions must let the clock move. A wake-up computed from `f64` seconds and truncated to
//! whole nanoseconds used to fire a hair before the update was due; the actor found nothing due,
//! set the timer to the same instant again, and spun forever (the paused clock only moves when
//! every task waits). A real-time watchdog turns that hang into a failure.

#![cfg(feature = "sim")]

use std::time::Duration;

use futures_util::StreamExt;
use gripper::wsg::sim::{Model, SessionKind, SimConfig, SimServer};
use gripper::wsg::{Client, UpdateOptions};

#[test]
fn auto_updates_under_a_paused_clock_do_not_spin() {
    let (done_tx, done) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_time()
            .start_paused(true)
            .build()
            .unwrap();
        rt.block_on(async {
            let sim = SimServer::in_memory(
                SimConfig::new(Model::Wsg50)
                    .with_part(40.0, 2.0)
                    .with_time_scale(1.0),
            );
            let (client_io, sim_io) = tokio::io::duplex(64 * 1024);
            sim.serve_stream(sim_io, SessionKind::Tcp);
            let client = Client::builder().attach(client_io);
            // Periods whose sums are not exact in binary floating point.
            for ms in [10, 13, 17, 23, 37, 50, 77, 110, 133, 190] {
                // Time passes between the streams, so each starts at another offset.
                tokio::time::sleep(Duration::from_millis(ms * 7 + 3)).await;
                let mut updates = client
                    .subscribe_width_mm(UpdateOptions::periodic(Duration::from_millis(ms)))
                    .await
                    .unwrap();
                for _ in 0..30 {
                    let next = tokio::time::timeout(Duration::from_secs(5), updates.next());
                    assert!(next.await.unwrap().is_some());
                }
            }
            client.close().await.unwrap();
        });
        let _ = done_tx.send(());
    });
    // Simulated time costs no wall time: this is seconds of margin for a slow machine.
    done.recv_timeout(Duration::from_secs(60))
        .expect("the simulator spun without letting the paused clock move");
}
