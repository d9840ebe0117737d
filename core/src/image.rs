//! Images (stub: the struct only; replaced by the full reader/writer).

/// Interleaved f32 pixels, row-major from the top row.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub channels: Vec<String>,
    pub data: Vec<f32>,
}

#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct ImageError(pub String);

/// Stub writer: PFM only.
pub fn write(image: &Image, path: impl AsRef<std::path::Path>) -> Result<(), ImageError> {
    use std::io::Write;
    let mut f = std::fs::File::create(path.as_ref()).map_err(|e| ImageError(e.to_string()))?;
    write!(f, "PF\n{} {}\n-1.0\n", image.width, image.height).map_err(|e| ImageError(e.to_string()))?;
    let nc = image.channels.len();
    for y in (0..image.height as usize).rev() {
        for x in 0..image.width as usize {
            for c in 0..3 {
                let v = image.data[(y * image.width as usize + x) * nc + c];
                f.write_all(&v.to_le_bytes()).map_err(|e| ImageError(e.to_string()))?;
            }
        }
    }
    Ok(())
}

pub fn write_atomic<F>(path: impl AsRef<std::path::Path>, produce: F) -> Result<(), ImageError>
where
    F: FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
{
    let mut f = std::fs::File::create(path.as_ref()).map_err(|e| ImageError(e.to_string()))?;
    produce(&mut f).map_err(|e| ImageError(e.to_string()))
}

impl Image {
    pub fn select_channels<S: AsRef<str>>(&self, names: &[S]) -> Result<Image, ImageError> {
        let idx: Vec<usize> = names
            .iter()
            .map(|n| self.channels.iter().position(|c| c == n.as_ref()).ok_or_else(|| ImageError("no channel".into())))
            .collect::<Result<_, _>>()?;
        let nc = self.channels.len();
        let data = self.data.chunks(nc).flat_map(|px| idx.iter().map(move |&i| px[i])).collect();
        Ok(Image {
            width: self.width,
            height: self.height,
            channels: names.iter().map(|n| n.as_ref().to_string()).collect(),
            data,
        })
    }
}
