//! Every picture `gripctl` writes, rendered to pixels with `resvg`: motion traces (`--plot`) of
//! the WSG and GRIPLINK simulators, and the SmartGrasp simulator's scene fetched over HTTP
//! (`smartgrasp image`). Each must parse, draw something, and hold the expected number of series
//! or parts.

mod common;

use std::path::{Path, PathBuf};

use common::{gripctl, Run, PATIENCE};
use resvg::tiny_skia::{Pixmap, Transform};
use serde_json::Value;
use tokio::io::{AsyncBufReadExt, AsyncReadExt, AsyncWriteExt, BufReader};
use tokio::net::TcpListener;

/// A fresh file path for test `name` under cargo's scratch directory for integration tests.
fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("pictures");
    std::fs::create_dir_all(&dir).expect("scratch directory");
    let path = dir.join(name);
    let _ = std::fs::remove_file(&path);
    path
}

/// Reads `path` as SVG, renders it, saves the pixels beside it (`.png`, to look at when a test
/// fails) and asserts it is not blank: a good share of its pixels differ from the background,
/// in more than two colours. Returns the document.
fn rendered(path: &Path) -> String {
    let svg = std::fs::read_to_string(path).expect("the picture was written");
    let tree = resvg::usvg::Tree::from_str(&svg, &resvg::usvg::Options::default())
        .unwrap_or_else(|e| panic!("{} is not valid SVG: {e}", path.display()));
    let size = tree.size().to_int_size();
    let mut pixmap = Pixmap::new(size.width(), size.height()).expect("a non-empty picture");
    resvg::render(&tree, Transform::default(), &mut pixmap.as_mut());
    let _ = pixmap.save_png(path.with_extension("png"));
    let pixels = pixmap.pixels();
    let background = pixels[0];
    let drawn = pixels.iter().filter(|p| **p != background).count();
    assert!(
        drawn * 100 > pixels.len(),
        "{}: only {drawn} of {} pixels drawn",
        path.display(),
        pixels.len()
    );
    let mut colours: Vec<_> = pixels
        .iter()
        .map(|p| (p.red(), p.green(), p.blue()))
        .collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(colours.len() > 2, "{}: {colours:?}", path.display());
    svg
}

/// The polylines of a trace with `mark` (see `cli/src/plot.rs`: data series have stroke width
/// 2, reference lines colour #FF8C00, state changes #787878).
fn count_polylines(svg: &str, mark: &str) -> usize {
    svg.lines()
        .filter(|l| l.contains("<polyline") && l.contains(mark))
        .count()
}

const SERIES: &str = r#"stroke-width="2""#;
const REFERENCE: &str = r##"stroke="#FF8C00""##;
const EVENT: &str = r##"stroke="#787878""##;

async fn run(args: &[&str]) -> Run {
    let mut all = vec!["--timeout", common::CALL_TIMEOUT];
    all.extend_from_slice(args);
    gripctl(&all).await
}

#[tokio::test]
async fn wsg_traces_draw_width_speed_and_force_with_the_commands_limits() {
    use gripper::wsg::sim::{Model, SimConfig, SimServer};
    let config = SimConfig::new(Model::Wsg50).with_part(40.0, 2.0);
    let server = SimServer::bind("127.0.0.1:0", config).await.expect("bind");
    let addr = server.local_addr().expect("TCP address").to_string();
    let wsg = |args: &[&str]| {
        let mut all = vec!["wsg", "--addr", addr.as_str()];
        all.extend_from_slice(args);
        let all: Vec<String> = all.iter().map(|s| s.to_string()).collect();
        async move { run(&all.iter().map(String::as_str).collect::<Vec<_>>()).await }
    };

    let home = scratch("wsg-home.svg");
    let out = wsg(&["home", "--plot", home.to_str().expect("UTF-8 path")]).await;
    assert!(out.ok().contains("homed"), "{out:#?}");
    let svg = rendered(&home);
    assert_eq!(count_polylines(&svg, SERIES), 3, "width, speed, force");
    // Homing has no target width; the force limit is drawn.
    assert_eq!(count_polylines(&svg, REFERENCE), 1);
    assert!(svg.contains("width (mm)") && svg.contains("speed (mm/s)"));
    assert!(svg.contains("force (N)") && svg.contains("time (s)"));
    assert!(svg.contains("E_SUCCESS"));

    let grasp = scratch("wsg-grasp.svg");
    let out = wsg(&[
        "--json",
        "grasp",
        "40",
        "--force",
        "30",
        "--plot",
        grasp.to_str().expect("UTF-8 path"),
    ])
    .await;
    out.ok();
    let lines = out.json_lines();
    // The samples as `watch` prints them, then the result.
    let (done, samples) = lines.split_last().expect("output");
    assert_eq!(done["done"], "grasped", "{out:#?}");
    assert!(!samples.is_empty());
    assert!(samples.iter().all(|s| s["width_mm"].is_number()));
    let svg = rendered(&grasp);
    assert_eq!(count_polylines(&svg, SERIES), 3);
    // The target width and the force limit.
    assert_eq!(count_polylines(&svg, REFERENCE), 2);
    assert!(svg.contains("target 40.0 mm") && svg.contains("force limit 30.0 N"));
    assert!(svg.contains("E_SUCCESS, grip state HOLDING"), "{svg}");

    // A failed grasp is drawn too, its status in the title.
    let failed = scratch("wsg-grasp-failed.svg");
    let release = scratch("wsg-release.svg");
    let out = wsg(&["release", "100", "--plot", release.to_str().expect("UTF-8")]).await;
    out.ok();
    assert_eq!(count_polylines(&rendered(&release), SERIES), 3);
    // The part is 40 mm wide: a grasp of a 90 mm part finds none.
    let out = wsg(&["grasp", "90", "--plot", failed.to_str().expect("UTF-8")]).await;
    assert!(out.failed().contains("E_CMD_FAILED"), "{out:#?}");
    assert!(rendered(&failed).contains("E_CMD_FAILED"));

    // Only motions are traced.
    let out = wsg(&["info", "--plot", "x.svg"]).await;
    assert!(out.failed().contains("--plot traces"), "{out:#?}");
}

#[tokio::test]
async fn griplink_traces_draw_the_position_with_state_changes_marked() {
    use gripper::griplink::sim::{SimConfig, SimDevice, SimServer};
    let config = SimConfig::et4()
        .device(0, Some(SimDevice::ieg_55_020().with_part(12.0)))
        .time_scale(0.0);
    let server = SimServer::bind("127.0.0.1:0", config).await.expect("bind");
    let addr = server.local_addr().to_string();
    let home = scratch("griplink-home.svg");
    let grip = scratch("griplink-grip.svg");
    for (command, path) in [("home", &home), ("grip", &grip)] {
        let file = path.to_str().expect("UTF-8 path");
        let out = run(&["griplink", "--addr", &addr, command, "--plot", file]).await;
        assert!(out.ok().contains("trace:"), "{out:#?}");
    }
    let svg = rendered(&home);
    assert_eq!(count_polylines(&svg, SERIES), 1, "position");
    assert!(svg.contains("position (mm)") && svg.contains("time (s)"));
    let svg = rendered(&grip);
    assert_eq!(count_polylines(&svg, SERIES), 1);
    // The recipe's no-part limit is the grip's target.
    assert_eq!(count_polylines(&svg, REFERENCE), 1, "{svg}");
    // At least the state the polls first saw is marked; the grip ends holding the part.
    assert!(count_polylines(&svg, EVENT) >= 1);
    assert!(svg.contains("DS_HOLDING") && svg.contains("force limit"));

    let out = run(&["griplink", "--addr", &addr, "state", "--plot", "x.svg"]).await;
    assert!(out.failed().contains("--plot traces"), "{out:#?}");
}

/// `gripctl smartgrasp image --http HTTP --out PATH`.
async fn image(http: &str, path: &Path, json: bool) -> Run {
    let file = path.to_str().expect("UTF-8 path");
    let mut args = vec!["smartgrasp", "image", "--http", http, "--out", file];
    if json {
        args.push("--json");
    }
    run(&args).await
}

#[tokio::test]
async fn the_smartgrasp_scene_shows_every_remaining_part() {
    use gripper::smartgrasp::sim::{SimConfig, SimServer};
    // GRASP_FEEDBACK OK takes the part out of the bin (a simulator option; SCHUNK's server
    // ignores feedback).
    let config = SimConfig {
        feedback_removes_objects: true,
        ..SimConfig::default()
    };
    let server = SimServer::bind("127.0.0.1:0", config).await.expect("bind");
    let monitor = server.serve_monitor("127.0.0.1:0").await.expect("bind");
    let http = monitor.local_addr().to_string();
    let addr = server.local_addr().to_string();

    let before = scratch("scene-before.svg");
    let out = image(&http, &before, true).await;
    assert_eq!(out.json()["content_type"], "image/svg+xml", "{out:#?}");
    let svg = rendered(&before);
    assert_eq!(svg.matches(r#"<g class="part""#).count(), 3);
    assert_eq!(svg.matches(r#"<g class="grasp""#).count(), 5);

    // A grasp reported OK takes its part out of the bin, and out of the picture.
    let grasp = run(&["smartgrasp", "--addr", &addr, "grasp", "--json"]).await;
    let picked: Value = grasp.json();
    run(&["smartgrasp", "--addr", &addr, "feedback", "ok"])
        .await
        .ok();
    let after = scratch("scene-after.svg");
    image(&http, &after, false).await.ok();
    let svg = rendered(&after);
    assert_eq!(svg.matches(r#"<g class="part""#).count(), 2);
    let gone = format!(
        r#"data-class="{}" data-instance="{}""#,
        picked["grasp"]["object_class"], picked["grasp"]["object_instance"]
    );
    assert!(!svg.contains(&gone), "{gone} still drawn: {picked}");
}

#[tokio::test]
async fn sim_smartgrasp_serves_its_scene_on_the_http_address() {
    let mut child = tokio::process::Command::new(env!("CARGO_BIN_EXE_gripctl"))
        .args(["sim", "smartgrasp", "--listen", "127.0.0.1:0"])
        .args(["--http", "127.0.0.1:0", "--copies", "2"])
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .kill_on_drop(true)
        .spawn()
        .expect("gripctl sim starts");
    let mut lines = BufReader::new(child.stdout.take().expect("piped")).lines();
    let url = tokio::time::timeout(PATIENCE, async {
        loop {
            let line = lines.next_line().await.expect("readable").expect("a line");
            if let Some(url) = line.strip_prefix("monitor: ") {
                return url.to_owned();
            }
        }
    })
    .await
    .expect("the simulator prints its monitor URL");
    let http = url
        .strip_prefix("http://")
        .and_then(|u| u.strip_suffix("/monitor/latest_result"))
        .unwrap_or_else(|| panic!("{url}"));
    let path = scratch("sim-scene.svg");
    image(http, &path, false).await.ok();
    assert_eq!(
        rendered(&path).matches(r#"<g class="part""#).count(),
        6,
        "two copies of the demo's three parts"
    );
}

/// A one-request HTTP server that answers `response` whatever it is asked.
async fn answering(response: &'static str) -> String {
    let listener = TcpListener::bind("127.0.0.1:0").await.expect("bind");
    let addr = listener.local_addr().expect("addr").to_string();
    tokio::spawn(async move {
        if let Ok((mut stream, _)) = listener.accept().await {
            let mut request = [0u8; 1024];
            let _ = stream.read(&mut request).await;
            let _ = stream.write_all(response.as_bytes()).await;
        }
    });
    addr
}

#[tokio::test]
async fn an_answer_that_is_not_an_image_is_a_clear_error_and_writes_nothing() {
    let html = answering(
        "HTTP/1.1 200 OK\r\nContent-Type: text/html\r\nContent-Length: 6\r\nConnection: close\r\n\r\n<html>",
    )
    .await;
    let path = scratch("not-an-image.svg");
    let out = image(&html, &path, true).await;
    out.failed_with("malformed", "text/html, not an image");
    assert!(!path.exists());

    let missing = answering(
        "HTTP/1.1 404 Not Found\r\nContent-Type: text/plain\r\nContent-Length: 0\r\nConnection: close\r\n\r\n",
    )
    .await;
    let out = image(&missing, &path, false).await;
    assert!(out.failed().contains("HTTP 404"), "{out:#?}");
    assert!(!path.exists());
}

#[test]
fn the_pictures_in_the_readme_render() {
    let docs = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../docs");
    let copy = |name: &str| {
        let path = scratch(name);
        std::fs::copy(docs.join(name), &path).expect("docs/ holds the README's pictures");
        path
    };
    let trace = rendered(&copy("wsg-grasp-trace.svg"));
    assert_eq!(count_polylines(&trace, SERIES), 3);
    assert_eq!(count_polylines(&trace, REFERENCE), 2);
    let scene = rendered(&copy("smartgrasp-scene.svg"));
    assert_eq!(scene.matches(r#"<g class="part""#).count(), 3);
}
