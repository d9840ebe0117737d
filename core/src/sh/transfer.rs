//! SH transfer channels (see the convention in [`crate::sh`]): `sh.0 … sh.K` (world-space
//! transfer `∫ V max(0, n·ω) Y_i dω`) and `albedo.R/G/B`; Lambertian radiance under distant
//! light `L` is `albedo/π · Σ_i transfer_i L_i`.

use super::{env::ShRgb, ShError, ShOrder};
use crate::Rgb;

/// The albedo channel names.
pub const ALBEDO_CHANNELS: [&str; 3] = ["albedo.R", "albedo.G", "albedo.B"];

/// The name of transfer coefficient `i`: `sh.i`.
pub fn sh_channel(i: usize) -> String {
    format!("sh.{i}")
}

/// Where an integrator writes transfer and albedo in its per-sample channel slice: `n²`
/// transfer values from `offset`, then the three albedo values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TransferChannels {
    pub order: ShOrder,
    pub offset: usize,
}

impl TransferChannels {
    pub fn new(order: ShOrder, offset: usize) -> TransferChannels {
        TransferChannels { order, offset }
    }

    /// `sh.0 … sh.K, albedo.R, albedo.G, albedo.B`, in the order they are written.
    pub fn names(&self) -> Vec<String> {
        (0..self.order.coeffs()).map(sh_channel).chain(ALBEDO_CHANNELS.iter().map(|s| s.to_string())).collect()
    }

    /// How many channels [`names`](Self::names) lists.
    pub fn len(&self) -> usize {
        self.order.coeffs() + 3
    }

    pub fn is_empty(&self) -> bool {
        false
    }

    /// Scales the transfer values in `aov` by a camera ray's weight `w` (the albedo stays): the
    /// relit image is then the weighted radiance ([`crate::integrator::PixelEstimator::weight_channels`]).
    pub fn weight(&self, aov: &mut [f32], w: f32) {
        let k = self.order.coeffs();
        if let Some(dst) = aov.get_mut(self.offset..self.offset + k) {
            dst.iter_mut().for_each(|v| *v *= w);
        }
    }

    /// Writes `transfer` (n² values) and `albedo` into `aov` (ignored where `aov` is too short).
    pub fn write(&self, aov: &mut [f32], transfer: &[f64], albedo: Rgb) {
        let k = self.order.coeffs();
        let Some(dst) = aov.get_mut(self.offset..self.offset + k + 3) else { return };
        for (d, t) in dst.iter_mut().zip(transfer.iter().take(k)) {
            *d = *t as f32;
        }
        dst[k..].copy_from_slice(&albedo.to_array());
    }
}

/// What a reader of transfer channels did not find.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TransferError {
    #[error("no SH transfer channels (sh.0, sh.1, …): render with an integrator that writes them, e.g. `-i ambientocclusion --param sh=true`")]
    NoTransfer,
    #[error("SH transfer channels sh.0…sh.{last} are present but sh.{missing} is missing")]
    Gap { last: usize, missing: usize },
    #[error("{count} SH transfer channels is not n² for an SH order n: {source}")]
    Order { count: usize, source: ShError },
    #[error("no albedo channels (albedo.R, albedo.G, albedo.B) beside the SH transfer channels")]
    NoAlbedo,
}

/// The channel indices of transfer and albedo in an image's channel list.
#[derive(Clone, Debug, PartialEq)]
pub struct TransferLayout {
    pub order: ShOrder,
    /// Channel index of `sh.i`, for `i < n²`.
    pub sh: Vec<usize>,
    pub albedo: [usize; 3],
}

impl TransferLayout {
    /// Finds `sh.0 … sh.K` (contiguous from 0, K + 1 a square) and `albedo.R/G/B` by name.
    pub fn find<S: AsRef<str>>(channels: &[S]) -> Result<TransferLayout, TransferError> {
        let pos = |name: &str| channels.iter().position(|c| c.as_ref() == name);
        let mut indices: Vec<(usize, usize)> = channels
            .iter()
            .enumerate()
            .filter_map(|(c, name)| {
                let i = name.as_ref().strip_prefix("sh.")?;
                // `sh.07` is not `sh.7`: only canonical decimal numbers count.
                let v: usize = i.parse().ok()?;
                (v.to_string() == i).then_some((v, c))
            })
            .collect();
        if indices.is_empty() {
            return Err(TransferError::NoTransfer);
        }
        indices.sort_unstable();
        let last = indices.last().map(|v| v.0).unwrap_or(0);
        for (want, (i, _)) in indices.iter().enumerate() {
            if *i != want {
                return Err(TransferError::Gap { last, missing: want });
            }
        }
        let count = indices.len();
        let order = ShOrder::from_coeffs(count).map_err(|source| TransferError::Order { count, source })?;
        let albedo = match (pos(ALBEDO_CHANNELS[0]), pos(ALBEDO_CHANNELS[1]), pos(ALBEDO_CHANNELS[2])) {
            (Some(r), Some(g), Some(b)) => [r, g, b],
            _ => return Err(TransferError::NoAlbedo),
        };
        Ok(TransferLayout { order, sh: indices.into_iter().map(|(_, c)| c).collect(), albedo })
    }
}

/// Lighting prepared for per-pixel shading: `L_i / π` per colour, f32, coefficient-major.
#[derive(Clone, Debug, PartialEq)]
pub struct TransferShader {
    light_over_pi: Vec<[f32; 3]>,
}

impl TransferShader {
    /// For lighting `light` (truncated or zero-padded to `order`).
    pub fn new(light: &ShRgb, order: ShOrder) -> TransferShader {
        let inv_pi = 1.0 / std::f64::consts::PI;
        let light_over_pi = (0..order.coeffs())
            .map(|i| light.coeffs.get(i).map_or([0.0; 3], |c| c.map(|v| (v * inv_pi) as f32)))
            .collect();
        TransferShader { light_over_pi }
    }

    /// `albedo/π · Σ_i transfer_i L_i` for one pixel whose channels are `px`.
    #[inline]
    pub fn shade(&self, layout: &TransferLayout, px: &[f32]) -> [f32; 3] {
        let mut acc = [0.0f32; 3];
        for (l, &c) in self.light_over_pi.iter().zip(&layout.sh) {
            let t = px[c];
            acc[0] += t * l[0];
            acc[1] += t * l[1];
            acc[2] += t * l[2];
        }
        [acc[0] * px[layout.albedo[0]], acc[1] * px[layout.albedo[1]], acc[2] * px[layout.albedo[2]]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sh::{zonal, SQRT_4PI};
    use glam::DVec3;

    #[test]
    fn names_write_find_round_trip() {
        let o = ShOrder::new(3).unwrap();
        let ch = TransferChannels::new(o, 2);
        let mut names = vec!["R".to_string(), "depth".to_string()];
        names.extend(ch.names());
        assert_eq!(names[2], "sh.0");
        assert_eq!(names[10], "sh.8");
        assert_eq!(&names[11..], &["albedo.R", "albedo.G", "albedo.B"]);
        let mut aov = vec![0.0f32; names.len()];
        let t: Vec<f64> = (0..9).map(|i| i as f64 * 0.5).collect();
        ch.write(&mut aov, &t, Rgb::new(0.1, 0.2, 0.3));
        assert_eq!(aov[2 + 4], 2.0);
        assert_eq!(aov[13], 0.3);
        // Readers get EXR channels in alphabetical order: sh.10 before sh.2 must not matter.
        let mut shuffled = names.clone();
        shuffled.sort();
        let layout = TransferLayout::find(&shuffled).unwrap();
        assert_eq!(layout.order, o);
        for i in 0..9 {
            assert_eq!(shuffled[layout.sh[i]], format!("sh.{i}"));
        }
        assert_eq!(shuffled[layout.albedo[1]], "albedo.G");
    }

    #[test]
    fn readers_refuse_incomplete_channel_sets() {
        let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
        assert_eq!(TransferLayout::find(&s(&["R", "G", "B"])), Err(TransferError::NoTransfer));
        let mut four = s(&["sh.0", "sh.1", "sh.3", "sh.2", "albedo.R", "albedo.G"]);
        assert_eq!(TransferLayout::find(&four), Err(TransferError::NoAlbedo));
        four.push("albedo.B".into());
        assert!(TransferLayout::find(&four).is_ok());
        assert_eq!(
            TransferLayout::find(&s(&["sh.0", "sh.2", "sh.3", "albedo.R", "albedo.G", "albedo.B"])),
            Err(TransferError::Gap { last: 3, missing: 1 })
        );
        assert!(matches!(
            TransferLayout::find(&s(&["sh.0", "sh.1", "albedo.R", "albedo.G", "albedo.B"])),
            Err(TransferError::Order { count: 2, .. })
        ));
        for e in [TransferError::NoTransfer, TransferError::NoAlbedo] {
            assert!(e.to_string().contains("albedo") || e.to_string().contains("sh.0"));
        }
    }

    /// Unoccluded transfer is the clamped cosine turned to n; under constant L the shade is
    /// albedo·L (white furnace), and under L = 1 + z it is albedo·(1 + 2n_z/3).
    #[test]
    fn shading_closed_forms() {
        let o = ShOrder::new(3).unwrap();
        let n = DVec3::new(0.3, -0.4, 0.6).normalize();
        let mut t = vec![0.0; 9];
        zonal::rotate_zh(&zonal::clamped_cosine(o), n, &mut t).unwrap();
        let mut px: Vec<f32> = t.iter().map(|v| *v as f32).collect();
        px.extend([0.5, 0.25, 1.0]);
        let layout = TransferLayout::find(&TransferChannels::new(o, 0).names()).unwrap();
        let mut light = ShRgb::zero(o);
        light.coeffs[0] = [2.0 * SQRT_4PI; 3];
        let v = TransferShader::new(&light, o).shade(&layout, &px);
        for (got, want) in v.iter().zip([1.0, 0.5, 2.0]) {
            assert!((got - want).abs() < 1e-6, "{got} vs {want}");
        }
        // L = 1 + z: L₀ = √4π, L₁₀ = √(4π/3).
        let mut light = ShRgb::zero(o);
        light.coeffs[0] = [SQRT_4PI; 3];
        light.coeffs[2] = [(4.0 * std::f64::consts::PI / 3.0).sqrt(); 3];
        let v = TransferShader::new(&light, o).shade(&layout, &px);
        let want = 0.5 * (1.0 + 2.0 * n.z / 3.0);
        assert!((v[0] as f64 - want).abs() < 1e-6, "{} vs {want}", v[0]);
    }
}
