//! `--plot FILE.svg`: a motion trace drawn as one SVG, panels stacked over a shared time axis.
//!
//! The picture is for a commissioning engineer: how the width fell, when the force rose, whether
//! the fingers bounced. Every panel names its quantity and unit, the title names the command and
//! its final status, the command's target and limits are dashed reference lines, and device state
//! changes are marked on the time axis.
//!
//! Drawn with `plotters`' SVG backend only: no fonts are loaded (text is left to the viewer), no
//! system libraries. Every data series is one `<polyline>` of stroke width 2 (nothing else is that
//! wide), every reference line one `<polyline>` in [`REFERENCE_COLOR`] and every event one in
//! [`EVENT_COLOR`]: the tests count them.

use std::path::Path;

use plotters::prelude::*;

use crate::error::{CliError, Kind};

/// Size of the picture, px: wide enough for a few seconds of 10 ms samples.
const WIDTH_PX: u32 = 900;
/// Height of each panel, px.
const PANEL_HEIGHT_PX: u32 = 240;
/// Height of the title strip, px.
const TITLE_HEIGHT_PX: u32 = 40;

/// The colour of reference lines (dark orange), and of nothing else.
pub const REFERENCE_COLOR: RGBColor = RGBColor(0xFF, 0x8C, 0x00);
/// The colour of event marks (grey), and of nothing else.
pub const EVENT_COLOR: RGBColor = RGBColor(0x78, 0x78, 0x78);

/// One quantity over time, e.g. the finger width in mm.
#[derive(Debug, Clone)]
pub struct Panel {
    /// The quantity, e.g. `width`.
    pub quantity: &'static str,
    /// Its unit, e.g. `mm`.
    pub unit: &'static str,
    /// The samples: seconds since the command started, value.
    pub samples: Vec<(f64, f64)>,
    /// Horizontal reference lines: a name (e.g. `target 20.0 mm`) and the value.
    pub references: Vec<(String, f64)>,
}

impl Panel {
    /// An empty panel of `quantity` in `unit`.
    pub fn new(quantity: &'static str, unit: &'static str) -> Panel {
        Panel {
            quantity,
            unit,
            samples: Vec::new(),
            references: Vec::new(),
        }
    }

    /// Adds a sample at `t_s` seconds; a value that is not finite (a device's ±INF) is left out.
    pub fn push(&mut self, t_s: f64, value: f64) {
        if t_s.is_finite() && value.is_finite() {
            self.samples.push((t_s, value));
        }
    }

    /// Adds a reference line, unless its value is not finite.
    pub fn reference(&mut self, name: impl Into<String>, value: f64) {
        if value.is_finite() {
            self.references.push((name.into(), value));
        }
    }

    /// Holds the last sample until `t_s`, so that the line reaches the command's final reply
    /// even when the value stopped changing (a device that sends updates only on change).
    pub fn hold_until(&mut self, t_s: f64) {
        if let Some(&(last_t, value)) = self.samples.last() {
            if t_s > last_t {
                self.samples.push((t_s, value));
            }
        }
    }

    fn value_range(&self) -> (f64, f64) {
        let values = self
            .samples
            .iter()
            .map(|&(_, v)| v)
            .chain(self.references.iter().map(|&(_, v)| v));
        let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
        if lo > hi {
            return (0.0, 1.0);
        }
        // A margin, and never a zero-height range (a constant value).
        let margin = ((hi - lo) * 0.08).max(0.5);
        (lo - margin, hi + margin)
    }
}

/// A trace: a title, panels sharing the time axis, and marked events (device state changes).
#[derive(Debug, Clone)]
pub struct Trace {
    /// The command and its final status.
    pub title: String,
    /// The panels, top to bottom.
    pub panels: Vec<Panel>,
    /// Events on the time axis: seconds since the start, and a label.
    pub events: Vec<(f64, String)>,
}

impl Trace {
    /// The trace as an SVG document.
    pub fn to_svg(&self) -> Result<String, CliError> {
        let mut svg = String::new();
        let panels = u32::try_from(self.panels.len().max(1)).unwrap_or(1);
        let size = (WIDTH_PX, TITLE_HEIGHT_PX + panels * PANEL_HEIGHT_PX);
        self.draw(SVGBackend::with_string(&mut svg, size).into_drawing_area())
            .map_err(|e| CliError::new(Kind::Output, format!("cannot draw the plot: {e}")))?;
        Ok(svg)
    }

    /// Writes the SVG to `path`.
    pub fn write(&self, path: &Path) -> Result<(), CliError> {
        let svg = self.to_svg()?;
        std::fs::write(path, svg).map_err(|e| {
            CliError::new(
                Kind::Output,
                format!("cannot write the plot to {}: {e}", path.display()),
            )
        })
    }

    /// The time axis: from 0 to the last sample or event, at least 10 ms.
    fn duration_s(&self) -> f64 {
        let last = self
            .panels
            .iter()
            .flat_map(|p| p.samples.iter().map(|&(t, _)| t))
            .chain(self.events.iter().map(|&(t, _)| t))
            .fold(0.0, f64::max);
        (last * 1.02).max(0.01)
    }

    fn draw<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
        root.fill(&WHITE)?;
        let body = root.titled(&self.title, ("sans-serif", 18))?;
        let areas = body.split_evenly((self.panels.len().max(1), 1));
        let duration_s = self.duration_s();
        let colors = [BLUE, RED, GREEN, MAGENTA, CYAN];
        for (i, (panel, area)) in self.panels.iter().zip(areas.iter()).enumerate() {
            let color = colors[i % colors.len()];
            let (lo, hi) = panel.value_range();
            let mut chart = ChartBuilder::on(area)
                .margin(8)
                .x_label_area_size(32)
                .y_label_area_size(64)
                .build_cartesian_2d(0.0..duration_s, lo..hi)?;
            chart
                .configure_mesh()
                .x_desc("time (s)")
                .y_desc(format!("{} ({})", panel.quantity, panel.unit))
                .light_line_style(WHITE.mix(0.0))
                .draw()?;
            chart
                .draw_series(LineSeries::new(
                    panel.samples.iter().copied(),
                    color.stroke_width(2),
                ))?
                .label(format!("{} ({})", panel.quantity, panel.unit))
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 2), (x + 16, y + 2)], color.filled())
                });
            for (name, value) in &panel.references {
                chart
                    .draw_series(LineSeries::new(
                        [(0.0, *value), (duration_s, *value)],
                        REFERENCE_COLOR.stroke_width(1),
                    ))?
                    .label(name.as_str())
                    .legend(|(x, y)| {
                        Rectangle::new([(x, y - 1), (x + 16, y + 1)], REFERENCE_COLOR.filled())
                    });
            }
            for (t, label) in &self.events {
                chart.draw_series(std::iter::once(PathElement::new(
                    [(*t, lo), (*t, hi)],
                    EVENT_COLOR,
                )))?;
                chart.draw_series(std::iter::once(Text::new(
                    label.clone(),
                    (*t, hi),
                    ("sans-serif", 11),
                )))?;
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::MiddleRight)
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()?;
        }
        root.present()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_series_and_reference_is_one_polyline() {
        let mut width = Panel::new("width", "mm");
        width.push(0.0, 80.0);
        width.push(0.5, 40.0);
        width.push(f64::NAN, 1.0);
        width.hold_until(1.0);
        width.reference("target 40.0 mm", 40.0);
        let mut force = Panel::new("force", "N");
        force.push(0.0, 0.0);
        force.push(0.6, 20.0);
        force.reference("limit 20 N", 20.0);
        force.reference("not a line", f64::INFINITY);
        let trace = Trace {
            title: "wsg grasp: E_SUCCESS".to_owned(),
            panels: vec![width, force],
            events: vec![(0.5, "HOLDING".to_owned())],
        };
        assert_eq!(trace.panels[0].samples.len(), 3);
        let svg = trace.to_svg().expect("draws");
        let polylines: Vec<&str> = svg.lines().filter(|l| l.contains("<polyline")).collect();
        let count = |mark: &str| polylines.iter().filter(|l| l.contains(mark)).count();
        assert_eq!(count(r#"stroke-width="2""#), 2, "{svg}");
        assert_eq!(count(r##"stroke="#FF8C00""##), 2, "{svg}");
        assert_eq!(count(r##"stroke="#787878""##), 2, "{svg}");
        assert!(svg.contains("width (mm)") && svg.contains("force (N)"));
        assert!(svg.contains("time (s)") && svg.contains("E_SUCCESS"));
    }
}
