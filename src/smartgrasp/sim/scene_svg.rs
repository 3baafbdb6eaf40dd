//! The simulator's "latest detection result": a top view of the bin as SVG, written by hand so the
//! library needs no plotting crate.
//!
//! The real kit serves a camera image with its detections at `/monitor/latest_result` (see
//! PROTOCOLS.md, seed 002); the simulator has no camera, so it draws what it knows: every part
//! still in the active project's scene with its class and instance, and every grasp it could
//! return for it, in the robot base frame seen from above (x to the right, y up, millimetres).
//!
//! The document is meant for people and for tests: each part is one `<g class="part">`, each
//! grasp one `<g class="grasp">` inside its part, with `data-*` attributes giving the numbers.

use std::fmt::Write as _;

use super::state::{SimGrasp, SimObject, SimState};
use crate::smartgrasp::types::Tool;

/// Size of the drawing, px.
const WIDTH_PX: f64 = 800.0;
const HEIGHT_PX: f64 = 600.0;
/// Room for the title above the bin and the axis labels around it, px.
const MARGIN_PX: f64 = 60.0;
/// Free space around the outermost part inside the bin, mm.
const BIN_MARGIN_MM: f64 = 80.0;
/// The smallest bin drawn, mm, so that one part does not fill the picture.
const MIN_BIN_MM: f64 = 300.0;
/// Grid spacing, mm.
const GRID_MM: f64 = 50.0;
/// Drawn diameter of a part, mm: the simulator's parts have a position, not a shape.
const PART_DIAMETER_MM: f64 = 40.0;
/// Fill colours by class (cycled).
const CLASS_COLORS: [&str; 6] = [
    "#4e79a7", "#f28e2b", "#59a14f", "#b07aa1", "#76b7b2", "#edc948",
];

/// The active project's scene as an SVG document: a top view of the bin (robot base frame, x to
/// the right, y up, mm) with every part still in it, its class and instance, and every grasp it
/// could return for it (finger stroke as a bar along the tool's x axis, a ring for a contact
/// tool; solid: active, dashed: other user-defined, dotted: model-free). Each part is one
/// `<g class="part">`, each grasp one `<g class="grasp">` inside it, with `data-*` attributes
/// giving the numbers. [`SimServer::serve_monitor`](super::SimServer::serve_monitor) serves it.
pub fn scene_svg(state: &SimState) -> String {
    let project = state
        .active_project()
        .and_then(|i| state.projects().get(usize::try_from(i).ok()?));
    let scene: &[SimObject] = project.map_or(&[], |p| &p.scene);
    let title = match state.active_project() {
        Some(i) if project.is_some() => format!(
            "SmartGrasp simulator, project {i}: {} part{} in the bin",
            scene.len(),
            if scene.len() == 1 { "" } else { "s" }
        ),
        _ => "SmartGrasp simulator: no active project".to_owned(),
    };
    draw(&title, scene)
}

/// Where an object is: its first grasp's point less that grasp's offset from the centre, m.
fn centre_m(object: &SimObject) -> Option<[f64; 2]> {
    let g = object.grasps.first().or(object.auto_grasp.as_ref())?;
    let [x, y, _] = g.pose.position_m;
    Some([
        x - f64::from(g.center_offset_um[0]) * 1e-6,
        y - f64::from(g.center_offset_um[1]) * 1e-6,
    ])
}

/// The grasps of an object: user-defined ones, then the model-free one.
fn grasps(object: &SimObject) -> impl Iterator<Item = (&SimGrasp, bool)> {
    let user = object.grasps.iter().map(|g| (g, false));
    user.chain(object.auto_grasp.iter().map(|g| (g, true)))
}

/// Millimetres in the base frame to pixels.
struct View {
    x0_mm: f64,
    y1_mm: f64,
    px_per_mm: f64,
    left_px: f64,
    top_px: f64,
}

impl View {
    fn fit(points_mm: &[[f64; 2]]) -> (View, [f64; 4]) {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in points_mm {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        if lo[0] > hi[0] {
            // An empty bin: centred where the demo's parts lie.
            (lo, hi) = ([450.0, 0.0], [450.0, 0.0]);
        }
        let mut bounds = [0.0; 4];
        for k in 0..2 {
            let centre = (lo[k] + hi[k]) / 2.0;
            let half = ((hi[k] - lo[k]) / 2.0 + BIN_MARGIN_MM).max(MIN_BIN_MM / 2.0);
            // On the grid, so the bin does not jitter as parts leave it.
            bounds[k] = ((centre - half) / GRID_MM).floor() * GRID_MM;
            bounds[k + 2] = ((centre + half) / GRID_MM).ceil() * GRID_MM;
        }
        let [x0, y0, x1, y1] = bounds;
        let px_per_mm = ((WIDTH_PX - 2.0 * MARGIN_PX) / (x1 - x0))
            .min((HEIGHT_PX - 2.0 * MARGIN_PX) / (y1 - y0));
        let view = View {
            x0_mm: x0,
            y1_mm: y1,
            px_per_mm,
            left_px: (WIDTH_PX - (x1 - x0) * px_per_mm) / 2.0,
            top_px: MARGIN_PX,
        };
        (view, bounds)
    }

    fn px(&self, [x_mm, y_mm]: [f64; 2]) -> (f64, f64) {
        (
            self.left_px + (x_mm - self.x0_mm) * self.px_per_mm,
            // SVG's y points down; the base frame's y, seen from above, up.
            self.top_px + (self.y1_mm - y_mm) * self.px_per_mm,
        )
    }
}

fn draw(title: &str, scene: &[SimObject]) -> String {
    let mut points_mm: Vec<[f64; 2]> = Vec::new();
    for object in scene {
        points_mm.extend(centre_m(object).map(|[x, y]| [x * 1e3, y * 1e3]));
        for (g, _) in grasps(object) {
            points_mm.push([g.pose.position_m[0] * 1e3, g.pose.position_m[1] * 1e3]);
        }
    }
    let (view, [x0, y0, x1, y1]) = View::fit(&points_mm);
    let mut svg = String::new();
    // `write!` to a String cannot fail.
    let _ = write!(
        svg,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{WIDTH_PX}" height="{HEIGHT_PX}" viewBox="0 0 {WIDTH_PX} {HEIGHT_PX}" font-family="sans-serif">
<rect width="100%" height="100%" fill="white"/>
<text x="{}" y="28" font-size="18" text-anchor="middle">{}</text>
"#,
        WIDTH_PX / 2.0,
        escape(title)
    );
    // The bin, its grid and axes.
    let (bx0, by0) = view.px([x0, y1]);
    let (bx1, by1) = view.px([x1, y0]);
    let _ = writeln!(
        svg,
        r##"<rect class="bin" x="{bx0:.1}" y="{by0:.1}" width="{:.1}" height="{:.1}" fill="#f4f1ea" stroke="#555" stroke-width="2"/>"##,
        bx1 - bx0,
        by1 - by0
    );
    let mut x = x0;
    while x <= x1 + 1e-9 {
        let (px, _) = view.px([x, y0]);
        let _ = writeln!(
            svg,
            r##"<line x1="{px:.1}" y1="{by0:.1}" x2="{px:.1}" y2="{by1:.1}" stroke="#ddd"/><text x="{px:.1}" y="{:.1}" font-size="11" text-anchor="middle">{x:.0}</text>"##,
            by1 + 14.0
        );
        x += GRID_MM;
    }
    let mut y = y0;
    while y <= y1 + 1e-9 {
        let (_, py) = view.px([x0, y]);
        let _ = writeln!(
            svg,
            r##"<line x1="{bx0:.1}" y1="{py:.1}" x2="{bx1:.1}" y2="{py:.1}" stroke="#ddd"/><text x="{:.1}" y="{:.1}" font-size="11" text-anchor="end">{y:.0}</text>"##,
            bx0 - 4.0,
            py + 4.0
        );
        y += GRID_MM;
    }
    let _ = writeln!(
        svg,
        r#"<text x="{:.1}" y="{:.1}" font-size="12" text-anchor="middle">x (mm), robot base frame, seen from above</text>
<text x="{:.1}" y="{:.1}" font-size="12" text-anchor="middle" transform="rotate(-90 {:.1} {:.1})">y (mm)</text>"#,
        (bx0 + bx1) / 2.0,
        by1 + 32.0,
        bx0 - 40.0,
        (by0 + by1) / 2.0,
        bx0 - 40.0,
        (by0 + by1) / 2.0,
    );
    for object in scene {
        draw_part(&mut svg, &view, object);
    }
    let _ = writeln!(
        svg,
        r##"<text x="12" y="{:.1}" font-size="11">solid: active grasp · dashed: other user-defined grasp · dotted: model-free grasp · bar: finger stroke · ring: contact tool</text>"##,
        HEIGHT_PX - 8.0
    );
    svg.push_str("</svg>\n");
    svg
}

fn draw_part(svg: &mut String, view: &View, object: &SimObject) {
    let color = CLASS_COLORS[usize::from(object.class_id) % CLASS_COLORS.len()];
    let _ = writeln!(
        svg,
        r#"<g class="part" data-class="{}" data-instance="{}">"#,
        object.class_id, object.instance
    );
    if let Some([x, y]) = centre_m(object) {
        let (cx, cy) = view.px([x * 1e3, y * 1e3]);
        let r = PART_DIAMETER_MM / 2.0 * view.px_per_mm;
        let _ = writeln!(
            svg,
            r##"<circle cx="{cx:.1}" cy="{cy:.1}" r="{r:.1}" fill="{color}" fill-opacity="0.75" stroke="#333"/>
<text x="{cx:.1}" y="{:.1}" font-size="12" text-anchor="middle">class {} #{}</text>"##,
            cy + r + 14.0,
            object.class_id,
            object.instance
        );
    }
    for (g, model_free) in grasps(object) {
        draw_grasp(svg, view, g, model_free);
    }
    svg.push_str("</g>\n");
}

fn draw_grasp(svg: &mut String, view: &View, g: &SimGrasp, model_free: bool) {
    let [x, y, _] = g.pose.position_m;
    let (gx, gy) = view.px([x * 1e3, y * 1e3]);
    let dash = if model_free {
        r#" stroke-dasharray="2 3""#
    } else if g.active {
        ""
    } else {
        r#" stroke-dasharray="6 4""#
    };
    let kind = if model_free {
        "model-free"
    } else if g.active {
        "active"
    } else {
        "user"
    };
    let _ = write!(
        svg,
        r#"<g class="grasp" data-tool="{}" data-kind="{kind}" data-stroke-um="{}">"#,
        u8::from(g.tool),
        g.stroke_um
    );
    match g.tool {
        Tool::Contact => {
            let r = 8.0 * view.px_per_mm;
            let _ = write!(
                svg,
                r##"<circle cx="{gx:.1}" cy="{gy:.1}" r="{r:.1}" fill="none" stroke="#c0392b" stroke-width="2"{dash}/>"##
            );
        }
        _ => {
            // The fingers close along the tool's x axis: seen from above, a bar as long as the
            // stroke through the grasp point, with a finger at each end.
            let axis = g.pose.orientation.rotate([1.0, 0.0, 0.0]);
            let norm = axis[0].hypot(axis[1]);
            let (ux, uy) = if norm > 1e-9 {
                (axis[0] / norm, axis[1] / norm)
            } else {
                (1.0, 0.0)
            };
            let half_px = f64::from(g.stroke_um) * 1e-3 / 2.0 * view.px_per_mm;
            // SVG's y is flipped.
            let (dx, dy) = (ux * half_px, -uy * half_px);
            let (ax, ay, bx, by) = (gx - dx, gy - dy, gx + dx, gy + dy);
            let _ = write!(
                svg,
                r##"<line x1="{ax:.1}" y1="{ay:.1}" x2="{bx:.1}" y2="{by:.1}" stroke="#c0392b" stroke-width="2"{dash}/><circle cx="{ax:.1}" cy="{ay:.1}" r="3" fill="#c0392b"/><circle cx="{bx:.1}" cy="{by:.1}" r="3" fill="#c0392b"/><text x="{:.1}" y="{:.1}" font-size="10" fill="#c0392b">{:.1} mm</text>"##,
                bx + 4.0,
                by,
                f64::from(g.stroke_um) * 1e-3
            );
        }
    }
    svg.push_str("</g>\n");
}

/// XML text escaping (the title is built here, but stays correct if it ever carries a name).
fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::super::state::{SimConfig, SimProject};
    use super::*;

    #[test]
    fn every_part_and_grasp_is_drawn() {
        let state = SimState::new(SimConfig::default());
        let svg = scene_svg(&state);
        assert_eq!(svg.matches(r#"<g class="part""#).count(), 3, "{svg}");
        // Demo: 2 + 1 user-defined grasps on class 1, 1 user-defined + 1 model-free on class 2.
        assert_eq!(svg.matches(r#"<g class="grasp""#).count(), 5);
        assert_eq!(svg.matches(r#"data-kind="model-free""#).count(), 1);
        assert!(svg.contains("class 2 #0") && svg.contains("86.0 mm"));
        assert!(svg.contains("3 parts in the bin"));
        assert!(svg.starts_with("<svg") && svg.ends_with("</svg>\n"));
    }

    #[test]
    fn an_empty_bin_and_no_project_still_draw() {
        let mut config = SimConfig {
            projects: vec![SimProject::from_scene(vec![])],
            ..SimConfig::default()
        };
        let svg = scene_svg(&SimState::new(config.clone()));
        assert_eq!(svg.matches(r#"<g class="part""#).count(), 0);
        assert!(svg.contains("0 parts in the bin") && svg.contains(r#"class="bin""#));
        config.active_project = None;
        assert!(scene_svg(&SimState::new(config)).contains("no active project"));
    }

    #[test]
    fn the_view_keeps_every_point_inside_the_picture() {
        let (view, [x0, y0, x1, y1]) = View::fit(&[[450.0, -120.0], [520.0, 40.0]]);
        assert!(x0 <= 450.0 - BIN_MARGIN_MM && x1 >= 520.0 + BIN_MARGIN_MM);
        assert!(y0 <= -120.0 - BIN_MARGIN_MM && y1 >= 40.0 + BIN_MARGIN_MM);
        for corner in [[x0, y0], [x1, y1]] {
            let (px, py) = view.px(corner);
            assert!((0.0..=WIDTH_PX).contains(&px) && (0.0..=HEIGHT_PX).contains(&py));
        }
        // y up: the higher point is drawn nearer the top.
        assert!(view.px([0.0, y1]).1 < view.px([0.0, y0]).1);
    }
}
