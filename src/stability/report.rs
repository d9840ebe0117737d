//! What `stability` writes: the table, `stability.json`, `summary.md` and `contact.png`.

use super::args::StabilityArgs;
use super::measure::Measures;
use super::variants::{Expect, Geometry, Kind, Variant};
use super::Setup;
use crate::cli::format::{fmt_g, num, viridis};
use crate::sweep::plot::register_font;
use penumbra_core::image::{self, Image};
use penumbra_core::spectrum::srgb_encode;
use serde_json::{json, Value};
use std::fmt::Write as _;
use std::path::Path;

/// One render of the study.
pub struct Row {
    pub integrator: String,
    /// `None`: the base render.
    pub variant: Option<String>,
    pub expect: Option<Expect>,
    /// World units the scene was moved (translations).
    pub distance: Option<f64>,
    pub m: Measures,
    pub seconds: f64,
    /// The gated measures over their tolerance.
    pub fails: Vec<&'static str>,
}

impl Row {
    pub fn new(
        integrator: &str,
        v: Option<(&Variant, Expect)>,
        extent: f64,
        m: Measures,
        seconds: f64,
        fails: Vec<&'static str>,
    ) -> Row {
        Row {
            integrator: integrator.to_string(),
            variant: v.map(|v| v.0.name.clone()),
            expect: v.map(|v| v.1),
            distance: v.and_then(|(v, _)| match v.kind {
                Kind::Translate(k) => Some(k * extent),
                _ => None,
            }),
            m,
            seconds,
            fails,
        }
    }

    fn variant_name(&self) -> &str {
        self.variant.as_deref().unwrap_or("base")
    }

    fn json(&self) -> Value {
        let opt = |v: Option<f64>| v.map(num).unwrap_or(Value::Null);
        json!({
            "integrator": self.integrator,
            "variant": self.variant_name(),
            "expect": match self.expect {
                None => "base".to_string(),
                Some(Expect::Same) if self.variant.as_deref().is_some_and(|v| v.starts_with("light-")) => {
                    "same (the image does not depend on the lights)".to_string()
                }
                Some(Expect::Same) => "same".to_string(),
                Some(Expect::Scaled(k)) => format!("scaled {k}"),
                Some(Expect::Changed) => "changed".to_string(),
            },
            "distance": opt(self.distance),
            "nonfinite": self.m.nonfinite,
            "negative": self.m.negative,
            "above_bound": self.m.above_bound,
            "max_z": opt(self.m.max_z),
            "frac_z3": opt(self.m.frac_z3),
            "rel_rmse": opt(self.m.rel_rmse),
            "worst_pixel": self.m.worst.map(|(x, y)| json!([x, y])),
            "seconds": num(self.seconds),
            "fails": self.fails,
        })
    }
}

fn opt_g(v: Option<f64>, prec: usize) -> String {
    v.map(|v| fmt_g(v, prec)).unwrap_or_else(|| "-".into())
}

/// Everything a report says.
pub struct Report<'a> {
    pub args: &'a StabilityArgs,
    pub setup: &'a Setup,
    pub geo: &'a Geometry,
    pub rows: &'a [Row],
    pub notes: &'a [String],
    pub exit_code: u8,
}

const HEADER: [&str; 10] =
    ["integrator", "variant", "nonfinite", "negative", ">bound", "max |z|", "|z|>3", "rel RMSE", "seconds", "verdict"];

impl Report<'_> {
    fn cells(r: &Row) -> [String; 10] {
        [
            r.integrator.clone(),
            r.variant_name().to_string(),
            r.m.nonfinite.to_string(),
            r.m.negative.to_string(),
            r.m.above_bound.map(|n| n.to_string()).unwrap_or_else(|| "-".into()),
            opt_g(r.m.max_z, 3),
            r.m.frac_z3.map(|f| format!("{:.1}%", 100.0 * f)).unwrap_or_else(|| "-".into()),
            opt_g(r.m.rel_rmse, 2),
            format!("{:.3}", r.seconds),
            if r.fails.is_empty() {
                if r.expect == Some(Expect::Changed) { "ok (changes)" } else { "ok" }.to_string()
            } else {
                format!("FAIL: {}", r.fails.join(", "))
            },
        ]
    }

    /// The terminal table: aligned columns.
    pub fn table(&self) -> String {
        let rows: Vec<[String; 10]> = self.rows.iter().map(Self::cells).collect();
        let mut width = HEADER.map(str::len);
        for r in &rows {
            for (w, c) in width.iter_mut().zip(r) {
                *w = (*w).max(c.chars().count());
            }
        }
        let line = |cells: &[String]| {
            let mut s = String::new();
            for (i, (c, w)) in cells.iter().zip(width).enumerate() {
                if i < 2 || i == 9 {
                    let _ = write!(s, "{c:<w$}  ");
                } else {
                    let _ = write!(s, "{c:>w$}  ");
                }
            }
            s.trim_end().to_string() + "\n"
        };
        let mut s = line(&HEADER.map(String::from));
        for r in &rows {
            s += &line(r);
        }
        for n in self.notes {
            s += &format!("note: {n}\n");
        }
        s += &format!("{}\n", self.verdict_line());
        s
    }

    fn verdict_line(&self) -> &'static str {
        match self.exit_code {
            super::EXIT_STABLE => "STABLE",
            super::EXIT_NONFINITE => "NON-FINITE VALUES",
            _ => "TOLERANCE EXCEEDED",
        }
    }

    pub fn json(&self) -> Value {
        let t = &self.setup.tolerances;
        let (w, h) = self.setup.resolution;
        json!({
            "scene": self.args.scene,
            "resolution": [w, h],
            "spp": self.args.spp,
            "seed": self.args.flags.seed,
            "extent": num(self.geo.extent),
            "center": self.geo.center,
            "tolerances": {
                "z": t.z.map(num),
                "negative": t.negative,
                "bound": t.bound,
                "far": num(t.far),
            },
            "notes": self.notes,
            "rows": self.rows.iter().map(Row::json).collect::<Vec<_>>(),
            "status": self.verdict_line(),
            "exit_code": self.exit_code,
        })
    }

    /// `summary.md`: the table, the error against the distance of the translations, notes.
    pub fn summary(&self) -> String {
        let mut s = format!("# Stability of {}\n\n", self.args.scene.display());
        let (w, h) = self.setup.resolution;
        let _ = writeln!(
            s,
            "{w}x{h} pixels, {} spp, seed {}; scene extent {} (bounding-box diagonal).\n",
            self.args.spp,
            self.args.flags.seed,
            fmt_g(self.geo.extent, 4)
        );
        s += &format!("| {} |\n|{}\n", HEADER.join(" | "), "---|".repeat(HEADER.len()));
        for r in self.rows {
            s += &format!("| {} |\n", Self::cells(r).join(" | "));
        }
        let far: Vec<&Row> = self.rows.iter().filter(|r| r.distance.is_some()).collect();
        if !far.is_empty() {
            s += "\n## Error against the distance from the origin\n\n";
            s += "Translations by multiples of the scene's extent: f32 positions hold ~7 digits, so \
                  the error grows with the distance; where it leaves the noise is where the integrator breaks down.\n\n";
            s += "| integrator | distance | max abs z | rel RMSE |\n|---|---|---|---|\n";
            for r in far {
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} |",
                    r.integrator,
                    opt_g(r.distance, 3),
                    opt_g(r.m.max_z, 3),
                    opt_g(r.m.rel_rmse, 2)
                );
            }
        }
        if !self.notes.is_empty() {
            s += "\n## Notes\n\n";
            for n in self.notes {
                s += &format!("- {n}\n");
            }
        }
        s += &format!("\n**{}** (exit code {})\n", self.verdict_line(), self.exit_code);
        s
    }

    pub fn write(&self, cells: &[ContactCell]) -> Result<(), String> {
        let dir = &self.args.output;
        let text = |p: &Path, t: &str| image::write_atomic(p, |w| w.write_all(t.as_bytes())).map_err(|e| e.to_string());
        text(&dir.join("stability.json"), &(serde_json::to_string_pretty(&self.json()).unwrap_or_default() + "\n"))?;
        text(&dir.join("summary.md"), &self.summary())?;
        let png = contact_sheet(cells)?;
        image::write_atomic(dir.join("contact.png"), |w| w.write_all(&png)).map_err(|e| e.to_string())
    }
}

/// Pixels on each side of the worst pixel in a contact-sheet crop.
const HALF: i64 = 4;
const CROP: usize = (2 * HALF + 1) as usize;
/// Magnification of the crops.
const ZOOM: usize = 4;
const NONFINITE: [u8; 3] = [255, 0, 255];
const NEGATIVE: [u8; 3] = [0, 255, 255];

/// One (integrator, variant) of the contact sheet: base, variant and |z| crops around the worst pixel.
pub struct ContactCell {
    integrator: String,
    variant: String,
    caption: String,
    crops: [Vec<[u8; 3]>; 3],
}

impl ContactCell {
    pub fn new(
        integrator: &str,
        variant: &str,
        base: &Image,
        img: &Image,
        factor: f64,
        zmap: &[f32],
        m: &Measures,
    ) -> ContactCell {
        let (cx, cy) =
            m.worst.map(|(x, y)| (x as i64, y as i64)).unwrap_or((base.width as i64 / 2, base.height as i64 / 2));
        let inside = |x: i64, y: i64| x >= 0 && y >= 0 && x < base.width as i64 && y < base.height as i64;
        let window = || (-HALF..=HALF).flat_map(move |dy| (-HALF..=HALF).map(move |dx| (cx + dx, cy + dy)));
        // Exposure: the base crop's brightest finite value maps to 1.
        let peak = window()
            .filter(|&(x, y)| inside(x, y))
            .flat_map(|(x, y)| base.pixel(x as u32, y as u32).to_vec())
            .filter(|v| v.is_finite())
            .fold(0.0f32, f32::max);
        let gain = if peak > 0.0 { 1.0 / peak } else { 1.0 };
        let tone = |img: &Image, k: f32| -> Vec<[u8; 3]> {
            window()
                .map(|(x, y)| {
                    if !inside(x, y) {
                        return [40, 40, 40];
                    }
                    let p = img.pixel(x as u32, y as u32);
                    if p.iter().any(|v| !v.is_finite()) {
                        NONFINITE
                    } else if p.iter().any(|&v| v < 0.0) {
                        NEGATIVE
                    } else {
                        std::array::from_fn(|c| (srgb_encode((p[c] / k * gain).clamp(0.0, 1.0)) * 255.0).round() as u8)
                    }
                })
                .collect()
        };
        let zcrop = window()
            .map(|(x, y)| {
                if !inside(x, y) || zmap.is_empty() {
                    return [40, 40, 40];
                }
                let z = zmap[(y * base.width as i64 + x) as usize];
                if z.is_nan() {
                    NONFINITE
                } else {
                    // |z| from 0 to 10 across the colour map.
                    viridis(z as f64 / 10.0)
                }
            })
            .collect();
        ContactCell {
            integrator: integrator.to_string(),
            variant: variant.to_string(),
            caption: format!("|z| {}", opt_g(m.max_z, 2)),
            crops: [tone(base, 1.0), tone(img, factor as f32), zcrop],
        }
    }
}

/// The contact sheet: a row per variant, a column per integrator, each cell the base, the
/// variant and the |z| map (viridis, 0 to 10; magenta non-finite, cyan negative) around that
/// render's worst pixel, magnified.
fn contact_sheet(cells: &[ContactCell]) -> Result<Vec<u8>, String> {
    use plotters::prelude::*;
    let mut integrators: Vec<&str> = Vec::new();
    let mut variants: Vec<&str> = Vec::new();
    for c in cells {
        if !integrators.contains(&c.integrator.as_str()) {
            integrators.push(&c.integrator);
        }
        if !variants.contains(&c.variant.as_str()) {
            variants.push(&c.variant);
        }
    }
    let tile = CROP * ZOOM;
    let (label_w, head_h, gap) = (110usize, 30usize, 12usize);
    let cell_w = 3 * tile + 2 * 2 + gap;
    let cell_h = tile + 16;
    let w = (label_w + integrators.len().max(1) * cell_w) as u32;
    let h = (head_h + variants.len().max(1) * cell_h) as u32;
    let mut rgb = vec![255u8; w as usize * h as usize * 3];
    register_font()?;
    {
        let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
        let e = |e: DrawingAreaErrorKind<_>| e.to_string();
        let font = ("sans-serif", 12).into_font().color(&BLACK);
        let small = ("sans-serif", 10).into_font().color(&RGBColor(70, 70, 70));
        root.draw(&Text::new("base | variant | |z| (0-10)", (4, 4), small.clone())).map_err(e)?;
        for (i, name) in integrators.iter().enumerate() {
            // About 7 px a character at 12 px: longer names are cut to their cell.
            let fit: String = name.chars().take(cell_w / 7).collect();
            root.draw(&Text::new(fit, ((label_w + i * cell_w) as i32, 16), font.clone())).map_err(e)?;
        }
        for (j, v) in variants.iter().enumerate() {
            let y0 = head_h + j * cell_h;
            root.draw(&Text::new(v.to_string(), (4, (y0 + tile / 2 - 6) as i32), font.clone())).map_err(e)?;
            for (i, name) in integrators.iter().enumerate() {
                let Some(c) = cells.iter().find(|c| c.integrator == *name && c.variant == *v) else { continue };
                let x0 = label_w + i * cell_w;
                for (k, crop) in c.crops.iter().enumerate() {
                    let ox = x0 + k * (tile + 2);
                    for (p, col) in crop.iter().enumerate() {
                        let (px, py) = ((ox + (p % CROP) * ZOOM) as i32, (y0 + (p / CROP) * ZOOM) as i32);
                        let colour = RGBColor(col[0], col[1], col[2]).filled();
                        root.draw(&Rectangle::new([(px, py), (px + ZOOM as i32, py + ZOOM as i32)], colour))
                            .map_err(e)?;
                    }
                }
                root.draw(&Text::new(c.caption.clone(), (x0 as i32, (y0 + tile + 2) as i32), small.clone()))
                    .map_err(e)?;
            }
        }
        root.present().map_err(e)?;
    }
    image::encode_png_rgb8(w, h, &rgb, Path::new("contact.png")).map_err(|e| e.to_string())
}
