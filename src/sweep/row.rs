//! What a sweep measures: one [`Row`] per render, and the error [`Metric`] it plots and
//! summarises.

/// One render of the sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    pub integrator: String,
    pub budget: u32,
    /// Samples per pixel actually rendered.
    pub spp: u32,
    /// Scene build (the pipeline's build report).
    pub build_s: f64,
    /// The integrator's render (its own clock).
    pub render_s: f64,
    /// Wall time around choose-integrator + build + render + film readout.
    pub total_s: f64,
    pub mae: f64,
    pub rmse: f64,
    pub psnr: f64,
    pub max_err: f64,
    pub relmse: f64,
    pub smape: f64,
    pub flip: Option<f64>,
    /// Non-finite (NaN or infinite) R, G, B values in the render.
    pub nan_count: u64,
}

/// An error metric, lower is better (PSNR is recorded but cannot be plotted on a log axis).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Metric {
    Mae,
    Rmse,
    #[value(name = "max_err", alias = "max-err")]
    MaxErr,
    Relmse,
    Smape,
    Flip,
}

impl Metric {
    pub fn column(self) -> &'static str {
        match self {
            Metric::Mae => "mae",
            Metric::Rmse => "rmse",
            Metric::MaxErr => "max_err",
            Metric::Relmse => "relmse",
            Metric::Smape => "smape",
            Metric::Flip => "flip",
        }
    }
    pub fn label(self) -> &'static str {
        match self {
            Metric::Mae => "MAE",
            Metric::Rmse => "RMSE",
            Metric::MaxErr => "max error",
            Metric::Relmse => "relMSE",
            Metric::Smape => "SMAPE",
            Metric::Flip => "FLIP",
        }
    }
    pub fn of(self, r: &Row) -> Option<f64> {
        Some(match self {
            Metric::Mae => r.mae,
            Metric::Rmse => r.rmse,
            Metric::MaxErr => r.max_err,
            Metric::Relmse => r.relmse,
            Metric::Smape => r.smape,
            Metric::Flip => r.flip?,
        })
    }
}
