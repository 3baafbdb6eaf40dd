//! Unit tests of the simulated controller, in simulated time (no sockets, no clock).

use std::time::Duration;

use super::controller::*;
use super::parse::parse_command;

fn run(c: &mut Controller, s: &mut Session, line: &str, now: Duration) -> Outcome {
    let cmd = parse_command(line).expect(line);
    c.execute(s, &cmd, now)
}

fn text(o: Outcome) -> String {
    match o {
        Outcome::Reply(r) => r,
        other => panic!("expected a reply, got {other:?}"),
    }
}

#[test]
fn grip_cycle_in_simulated_time() {
    let cfg = SimConfig::et4().device(0, Some(SimDevice::ieg_55_020().with_part(12.0)));
    let mut c = Controller::new(cfg);
    let mut s = Session::default();
    let t0 = Duration::ZERO;
    assert_eq!(text(run(&mut c, &mut s, "GRIP(0,0)", t0)), "ERR 04");
    let Outcome::Wait(home) = run(&mut c, &mut s, "HOME(0)", t0) else {
        panic!("HOME must block")
    };
    assert_eq!(c.poll(&s, &home, t0), None);
    let t1 = c.next_wake(&home, t0);
    assert_eq!(t1, Duration::from_millis(400)); // 20 mm at 50 mm/s
    assert_eq!(c.poll(&s, &home, t1).as_deref(), Some("ACK"));
    assert_eq!(
        text(run(&mut c, &mut s, "DEVSTATE[0]?", t1)),
        "DEVSTATE[0]=2"
    );
    assert_eq!(
        text(run(
            &mut c,
            &mut s,
            "GRIPCFG[0][1]=[\"part\",5000,18000,50000,0,0,0,0,0]",
            t1
        )),
        "GRIPCFG[0][1]=[\"part\",5000,18000,50000,0,0,0,0,0]"
    );
    assert_eq!(text(run(&mut c, &mut s, "GRIP(0,1)", t1)), "ACK");
    let Outcome::Wait(wstr) = run(&mut c, &mut s, "WSTR[0]?", t1) else {
        panic!("WSTR must wait while moving")
    };
    let t2 = c.next_wake(&wstr, t1);
    assert_eq!(c.poll(&s, &wstr, t2).as_deref(), Some("WSTR[0]=5"));
    assert_eq!(
        text(run(&mut c, &mut s, "VALUE[0][0]?", t2)),
        "VALUE[0][0]=12000"
    );
    assert_eq!(
        text(run(&mut c, &mut s, "VALUEF[0][0]?", t2)),
        "VALUEF[0][0]=12"
    );
    assert_eq!(text(run(&mut c, &mut s, "GRIP(0,1)", t2)), "ERR 19");
    s.verbose = true;
    assert_eq!(
        text(run(&mut c, &mut s, "GRIP(0,1)", t2)),
        "ERR 19 Invalid state"
    );
    assert_eq!(text(run(&mut c, &mut s, "RELEASE(0,1)", t2)), "ACK");
    let t3 = t2 + Duration::from_secs(1);
    assert_eq!(
        text(run(&mut c, &mut s, "DEVSTATE[0]?", t3)),
        "DEVSTATE[0]=3"
    );
    assert_eq!(
        text(run(&mut c, &mut s, "VALUEF[0][0]?", t3)),
        "VALUEF[0][0]=18"
    );
}

#[test]
fn waitval_and_wstr_in_simulated_time() {
    let mut c = Controller::new(SimConfig {
        wstr_timeout: Duration::from_millis(100),
        ..SimConfig::et4()
    });
    let mut s = Session::default();
    let ms = Duration::from_millis;
    let Outcome::Wait(home) = run(&mut c, &mut s, "HOME(0)", ms(0)) else {
        panic!("HOME must block")
    };
    assert_eq!(c.poll(&s, &home, ms(400)).as_deref(), Some("ACK"));
    // Pre-position from 20 mm to 0 mm at 50 mm/s: 400 ms of motion.
    assert_eq!(text(run(&mut c, &mut s, "SETVALF(0,0,0)", ms(400))), "ACK");
    let Outcome::Wait(wait) = run(&mut c, &mut s, "WAITVAL(0,0,10000,1000,1000)", ms(400)) else {
        panic!("WAITVAL must wait")
    };
    assert_eq!(c.poll(&s, &wait, ms(500)), None); // 15 mm
    assert_eq!(c.next_wake(&wait, ms(500)), ms(505));
    // At 600 ms the fingers are at 10 mm.
    assert_eq!(c.poll(&s, &wait, ms(600)).as_deref(), Some("ACK"));
    // A window the fingers never reach: E_TIMEOUT at the WAITVAL's own timeout.
    let Outcome::Wait(wait) = run(&mut c, &mut s, "WAITVAL(0,0,30000,10,1000)", ms(600)) else {
        panic!("WAITVAL must wait")
    };
    assert_eq!(c.poll(&s, &wait, ms(1599)), None);
    assert_eq!(c.poll(&s, &wait, ms(1600)).as_deref(), Some("ERR 05"));
    // WSTR on an idle port waits for a transition and times out (3.4.10); so does a WSTR
    // during a motion that outlasts it.
    let Outcome::Wait(wstr) = run(&mut c, &mut s, "WSTR[0]?", ms(1600)) else {
        panic!("WSTR must wait on an idle port")
    };
    assert_eq!(c.next_wake(&wstr, ms(1600)), ms(1700));
    assert_eq!(c.poll(&s, &wstr, ms(1699)), None);
    assert_eq!(c.poll(&s, &wstr, ms(1700)).as_deref(), Some("ERR 05"));
    assert_eq!(c.wstr_timeouts(0), 1);
    c.set_time_scale(100.0);
    assert_eq!(
        text(run(&mut c, &mut s, "SETVAL(0,0,20000)", ms(1700))),
        "ACK"
    );
    let Outcome::Wait(wstr) = run(&mut c, &mut s, "WSTR[0]?", ms(1700)) else {
        panic!("WSTR must wait while moving")
    };
    // The motion takes 0.4 s x 100; WSTR gives up after 0.1 s x 100.
    let deadline = ms(1700) + Duration::from_secs(10);
    assert_eq!(c.next_wake(&wstr, ms(1700)), deadline);
    assert_eq!(c.poll(&s, &wstr, deadline - ms(1)), None);
    assert_eq!(c.poll(&s, &wstr, deadline).as_deref(), Some("ERR 05"));
}

fn home(c: &mut Controller, s: &mut Session) -> Duration {
    let Outcome::Wait(home) = run(c, s, "HOME(0)", Duration::ZERO) else {
        panic!("HOME must block")
    };
    let done = c.next_wake(&home, Duration::ZERO);
    assert_eq!(c.poll(s, &home, done).as_deref(), Some("ACK"));
    done
}

/// A WSTR answers the transition of the command before it even when it came first; the one
/// WSTR right after answers at once too ("issued twice", 3.4.10); the next one waits.
#[test]
fn wstr_pending_and_issued_twice() {
    let mut c = Controller::new(SimConfig::et4().wstr_timeout(Duration::from_secs(1)));
    let mut s = Session::default();
    let t = home(&mut c, &mut s);
    assert_eq!(text(run(&mut c, &mut s, "GRIP(0,0)", t)), "ACK");
    let later = t + Duration::from_secs(5); // the grip ended before the WSTR came
    assert_eq!(text(run(&mut c, &mut s, "WSTR[0]?", later)), "WSTR[0]=4");
    assert_eq!(text(run(&mut c, &mut s, "WSTR[0]?", later)), "WSTR[0]=4");
    let Outcome::Wait(third) = run(&mut c, &mut s, "WSTR[0]?", later) else {
        panic!("a third WSTR waits for a transition")
    };
    assert_eq!(
        c.poll(&s, &third, later + Duration::from_secs(1))
            .as_deref(),
        Some("ERR 05")
    );
    // A transition that happens while a WSTR waits answers it.
    let Outcome::Wait(wstr) = run(&mut c, &mut s, "WSTR[0]?", later) else {
        panic!("WSTR waits")
    };
    assert_eq!(text(run(&mut c, &mut s, "DISABLE(0)", later)), "ACK");
    assert_eq!(c.poll(&s, &wstr, later).as_deref(), Some("WSTR[0]=2"));
}

/// RELEASE from DS_RELEASED ends with no transition (3.4.7): WSTR times out although the
/// fingers moved; WAITVAL on the position sees the end.
#[test]
fn release_from_released_is_no_transition() {
    let mut c = Controller::new(SimConfig::et4().wstr_timeout(Duration::from_secs(2)));
    let mut s = Session::default();
    let t = home(&mut c, &mut s);
    // Default recipe 0 releases to the open end, where HOME left the fingers: the shortest
    // motion.
    assert_eq!(text(run(&mut c, &mut s, "RELEASE(0,0)", t)), "ACK");
    let t = t + MIN_MOTION_TIME;
    assert_eq!(
        text(run(&mut c, &mut s, "DEVSTATE[0]?", t)),
        "DEVSTATE[0]=3"
    );
    assert_eq!(text(run(&mut c, &mut s, "SETVAL(0,0,5000)", t)), "ACK");
    let t = t + Duration::from_secs(1);
    assert_eq!(
        text(run(&mut c, &mut s, "VALUE[0][0]?", t)),
        "VALUE[0][0]=5000"
    );
    assert_eq!(text(run(&mut c, &mut s, "RELEASE(0,0)", t)), "ACK");
    let Outcome::Wait(wstr) = run(&mut c, &mut s, "WSTR[0]?", t) else {
        panic!("WSTR waits")
    };
    let Outcome::Wait(waitval) = run(&mut c, &mut s, "WAITVAL(0,0,20000,0,5000)", t) else {
        panic!("WAITVAL waits")
    };
    let end = t + Duration::from_millis(300); // 15 mm at 50 mm/s
    assert_eq!(c.poll(&s, &waitval, end - Duration::from_millis(1)), None);
    assert_eq!(c.poll(&s, &waitval, end).as_deref(), Some("ACK"));
    assert_eq!(c.poll(&s, &wstr, end), None);
    let deadline = t + Duration::from_secs(2);
    assert_eq!(c.poll(&s, &wstr, deadline).as_deref(), Some("ERR 05"));
}

/// WAITVAL is reach/cross (3.4.12): a window of size 0 that the value steps over is ACKed,
/// from below and from above; a value moving away times out.
#[test]
fn waitval_reaches_or_crosses_a_zero_window() {
    let mut c = Controller::new(SimConfig::et4());
    let mut s = Session::default();
    let ms = Duration::from_millis;
    let t = home(&mut c, &mut s); // fingers at 20 mm
    assert_eq!(text(run(&mut c, &mut s, "SETVALF(0,0,0)", t)), "ACK");
    let Outcome::Wait(down) = run(&mut c, &mut s, "WAITVAL(0,0,10013,0,1000)", t) else {
        panic!("WAITVAL waits")
    };
    let Outcome::Wait(away) = run(&mut c, &mut s, "WAITVAL(0,0,20500,0,1000)", t) else {
        panic!("WAITVAL waits")
    };
    // 50 mm/s: 9.95 mm (below 10.013) after 201 ms, sampled at 5 ms steps.
    assert_eq!(c.poll(&s, &down, t + ms(150)), None);
    assert_eq!(c.poll(&s, &down, t + ms(205)).as_deref(), Some("ACK"));
    assert_eq!(c.poll(&s, &away, t + ms(999)), None);
    assert_eq!(c.poll(&s, &away, t + ms(1000)).as_deref(), Some("ERR 05"));
    let t = t + ms(1000); // at 0 mm
    assert_eq!(text(run(&mut c, &mut s, "SETVAL(0,0,20000)", t)), "ACK");
    let Outcome::Wait(up) = run(&mut c, &mut s, "WAITVALF(0,0,7.0071,0,1000)", t) else {
        panic!("WAITVAL waits")
    };
    assert_eq!(c.poll(&s, &up, t + ms(100)), None);
    assert_eq!(c.poll(&s, &up, t + ms(145)).as_deref(), Some("ACK"));
}

/// GRIP, RELEASE and HOME re-enable a gripper in DS_FAULT (3.4.1); the state keeps its start
/// value while the fingers move; SETVAL does not re-enable. ENABLE puts a gripper in state 2,
/// not the sensors' state 6 (chapter 5).
#[test]
fn fault_is_left_by_grip_release_home_and_enable() {
    let cfg = SimConfig::et4().device(0, Some(SimDevice::ieg_55_020().with_part(12.0)));
    let mut c = Controller::new(cfg);
    let mut s = Session::default();
    let ms = Duration::from_millis;
    let t = home(&mut c, &mut s);
    c.inject_fault(0, t);
    assert_eq!(text(run(&mut c, &mut s, "SETVAL(0,0,1000)", t)), "ERR 19");
    assert_eq!(text(run(&mut c, &mut s, "GRIP(0,0)", t)), "ACK");
    // Re-enabling first (3.4.1), then 8 mm at 50 mm/s.
    let t = t + DEFAULT_ENABLE_TIME;
    assert_eq!(
        text(run(&mut c, &mut s, "DEVSTATE[0]?", t + ms(10))),
        "DEVSTATE[0]=7"
    );
    assert_eq!(
        text(run(&mut c, &mut s, "DEVSTATE[0]?", t + ms(160))),
        "DEVSTATE[0]=5"
    );
    let t = t + ms(160);
    c.inject_fault(0, t);
    assert_eq!(text(run(&mut c, &mut s, "RELEASE(0,0)", t)), "ACK");
    let t = t + DEFAULT_ENABLE_TIME;
    assert_eq!(
        text(run(&mut c, &mut s, "DEVSTATE[0]?", t + ms(200))),
        "DEVSTATE[0]=3"
    );
    let t = t + ms(200);
    c.inject_fault(0, t);
    assert_eq!(text(run(&mut c, &mut s, "ENABLE(0)", t)), "ACK");
    assert_eq!(
        text(run(&mut c, &mut s, "DEVSTATE[0]?", t)),
        "DEVSTATE[0]=2"
    );
    assert_eq!(text(run(&mut c, &mut s, "CLAMP(0,1)", t)), "ERR 19");
    assert_eq!(text(run(&mut c, &mut s, "DISABLE(0)", t)), "ACK");
    assert_eq!(text(run(&mut c, &mut s, "CLAMP(0,1)", t)), "ACK");
    assert_eq!(text(run(&mut c, &mut s, "ENABLE(0)", t)), "ACK");
    assert_eq!(
        text(run(&mut c, &mut s, "DEVSTATE[0]?", t)),
        "DEVSTATE[0]=2"
    );
}

/// Every device ships with recipes that grip towards the closed end and release to the open
/// end (the simulator's choice; the manual lists no factory recipes).
#[test]
fn default_recipes_grip_closed_and_release_open() {
    let mut c = Controller::new(SimConfig::et4().time_scale(0.0));
    let mut s = Session::default();
    let z = Duration::ZERO;
    assert_eq!(
        text(run(&mut c, &mut s, "GRIPCFG[0][0]?", z)),
        "GRIPCFG[0][0]=[\"default\",0,20000,50000,0,0,0,0,0]"
    );
    assert_eq!(
        text(run(&mut c, &mut s, "GRIPCFGF[2][15]?", z)),
        "GRIPCFGF[2][15]=[\"default\",0,85,50,0,0,0,0,0]"
    );
}

#[test]
fn ports_and_devices() {
    let mut c = Controller::new(SimConfig::et4().time_scale(0.0));
    let mut s = Session::default();
    let z = Duration::ZERO;
    assert_eq!(text(run(&mut c, &mut s, "DEVVID[1]?", z)), "DEVVID[1]=-1");
    assert_eq!(text(run(&mut c, &mut s, "DEVPID[1]?", z)), "ERR 04");
    assert_eq!(
        text(run(&mut c, &mut s, "DEVSTATE[1]?", z)),
        "DEVSTATE[1]=0"
    );
    assert_eq!(text(run(&mut c, &mut s, "DEVSTATE[4]?", z)), "ERR 11");
    assert_eq!(text(run(&mut c, &mut s, "DEVPID[2]?", z)), "DEVPID[2]=50");
    assert_eq!(text(run(&mut c, &mut s, "DEVASSERT(0,815,20)", z)), "ACK");
    assert_eq!(
        text(run(&mut c, &mut s, "DEVASSERT(0,815,50)", z)),
        "ERR 25"
    );
    let mut master = Controller::new(SimConfig {
        role: Role::Master,
        ..SimConfig::wpg()
    });
    assert_eq!(master.port_count(), 32);
    assert_eq!(
        text(run(&mut master, &mut s, "DEVVID[31]?", z)),
        "DEVVID[31]=-1"
    );
}

/// Only GRIP, RELEASE and HOME re-enable a Weiss gripper (3.4.1): FLEXGRIP, FLEXRELEASE and
/// SETVAL on a gripper in DS_FAULT or disabled by DISABLE are refused and leave it as it is;
/// after ENABLE they work.
#[test]
fn only_grip_release_and_home_re_enable() {
    for disable in ["DISABLE(0)", "fault"] {
        let mut c = Controller::new(SimConfig::et4());
        let mut s = Session::default();
        let t = home(&mut c, &mut s);
        if disable == "fault" {
            c.inject_fault(0, t);
        } else {
            assert_eq!(text(run(&mut c, &mut s, disable, t)), "ACK");
        }
        let state = text(run(&mut c, &mut s, "DEVSTATE[0]?", t));
        for line in [
            "FLEXGRIP(0,0,10000,0,0)",
            "FLEXGRIPF(0,0,10,0,0)",
            "FLEXRELEASE(0,10000,0,0)",
            "FLEXRELEASEF(0,10,0,0)",
            "SETVAL(0,0,5000)",
            "SETVALF(0,0,5)",
        ] {
            assert_eq!(
                text(run(&mut c, &mut s, line, t)),
                "ERR 19",
                "{disable}: {line}"
            );
            let later = t + Duration::from_secs(1);
            assert_eq!(text(run(&mut c, &mut s, "DEVSTATE[0]?", later)), state);
            assert_eq!(
                text(run(&mut c, &mut s, "VALUE[0][0]?", later)),
                "VALUE[0][0]=20000",
                "{disable}: {line} moved the fingers"
            );
            // CLAMP is only allowed while the actuator is off (3.4.9).
            if disable == "DISABLE(0)" {
                assert_eq!(text(run(&mut c, &mut s, "CLAMP(0,1)", later)), "ACK");
            }
        }
        let t = t + Duration::from_secs(1);
        assert_eq!(text(run(&mut c, &mut s, "ENABLE(0)", t)), "ACK");
        assert_eq!(text(run(&mut c, &mut s, "SETVAL(0,0,5000)", t)), "ACK");
        let t = t + Duration::from_secs(1);
        assert_eq!(
            text(run(&mut c, &mut s, "VALUE[0][0]?", t)),
            "VALUE[0][0]=5000"
        );
    }
}

/// A RELEASE from DS_FAULT with the fingers at the release limit already: the gripper re-enables
/// first (3.4.1), so the state does not change at the instant of the ACK; it reads DS_FAULT
/// until the re-enable time has passed, then DS_RELEASED.
#[test]
fn a_release_from_fault_at_the_limit_ends_after_the_re_enable() {
    let mut c = Controller::new(SimConfig::et4());
    let mut s = Session::default();
    let t = home(&mut c, &mut s); // at the release limit, 20 mm
    c.inject_fault(0, t);
    assert_eq!(text(run(&mut c, &mut s, "RELEASE(0,0)", t)), "ACK");
    let enabled = t + DEFAULT_ENABLE_TIME + MIN_MOTION_TIME;
    for at in [t, enabled - Duration::from_millis(1)] {
        assert_eq!(
            text(run(&mut c, &mut s, "DEVSTATE[0]?", at)),
            "DEVSTATE[0]=7"
        );
    }
    assert_eq!(
        text(run(&mut c, &mut s, "DEVSTATE[0]?", enabled)),
        "DEVSTATE[0]=3"
    );
}

/// A motion with nothing to do does not end at the instant of its ACK either (a device needs a
/// control cycle to see that it is there): at least [`MIN_MOTION_TIME`].
#[test]
fn a_zero_length_motion_takes_the_minimum_time() {
    let mut c = Controller::new(SimConfig::et4());
    let mut s = Session::default();
    let t = home(&mut c, &mut s);
    assert_eq!(text(run(&mut c, &mut s, "RELEASE(0,0)", t)), "ACK");
    assert_eq!(
        text(run(&mut c, &mut s, "DEVSTATE[0]?", t)),
        "DEVSTATE[0]=2"
    );
    assert_eq!(
        text(run(&mut c, &mut s, "DEVSTATE[0]?", t + MIN_MOTION_TIME)),
        "DEVSTATE[0]=3"
    );
}
