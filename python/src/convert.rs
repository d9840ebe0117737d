//! Images between Rust and numpy: renders handed over without a copy, arrays and files read
//! into the library's [`Image`], `read_image` and `write_image`.

use crate::scene::Render;
use numpy::ndarray::{Array2, Array3};
use numpy::{PyArray2, PyArray3, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use penumbra_core::image::{self, Image};
use pyo3::exceptions::{PyIOError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// An `(H, W, 3)` float32 array that owns `data` (moved, not copied), and its buffer's address.
pub fn rgb_array(py: Python<'_>, w: u32, h: u32, data: Vec<f32>) -> PyResult<(Bound<'_, PyArray3<f32>>, usize)> {
    let address = data.as_ptr() as usize;
    let a =
        Array3::from_shape_vec((h as usize, w as usize, 3), data).map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok((PyArray3::from_owned_array(py, a), address))
}

/// The image's R, G, B as an `(H, W, 3)` array (without a copy when those are its only
/// channels) and each other channel as an `(H, W)` array, and the RGB buffer's address.
pub fn split_image(py: Python<'_>, img: Image) -> PyResult<(Bound<'_, PyArray3<f32>>, Bound<'_, PyDict>, usize)> {
    let (w, h, nc) = (img.width, img.height, img.channels.len());
    let channels = PyDict::new(py);
    let rgb = img.rgb_indices().ok_or_else(|| PyValueError::new_err("the image has no R, G, B channels"))?;
    if nc == 3 && rgb == [0, 1, 2] {
        let (a, address) = rgb_array(py, w, h, img.data)?;
        return Ok((a, channels, address));
    }
    let n = img.npixels();
    let mut rgb_data = Vec::with_capacity(n * 3);
    let mut extra: Vec<Vec<f32>> = vec![Vec::with_capacity(n); nc];
    for px in img.data.chunks_exact(nc.max(1)) {
        rgb_data.extend(rgb.iter().map(|&c| px[c]));
        for (c, v) in px.iter().enumerate() {
            if !rgb.contains(&c) {
                extra[c].push(*v);
            }
        }
    }
    for (c, values) in extra.into_iter().enumerate() {
        if rgb.contains(&c) {
            continue;
        }
        let a = Array2::from_shape_vec((h as usize, w as usize), values)
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        channels.set_item(&img.channels[c], PyArray2::from_owned_array(py, a))?;
    }
    let (a, address) = rgb_array(py, w, h, rgb_data)?;
    Ok((a, channels, address))
}

/// An array as an image: `(H, W, 3)` is R, G, B; `(H, W, C)` needs `names` (C of them);
/// `(H, W)` is one channel named `names[0]` (default `Y`). Any float or integer dtype.
pub fn array_image(obj: &Bound<'_, PyAny>, names: Option<Vec<String>>) -> PyResult<Image> {
    let np = obj.py().import("numpy")?;
    let arr = np.call_method1("ascontiguousarray", (obj, "float32"))?;
    let view: PyReadonlyArrayDyn<f32> = arr.extract()?;
    let shape = view.shape().to_vec();
    let (h, w, c) = match shape.as_slice() {
        [h, w] => (*h, *w, 1),
        [h, w, c] => (*h, *w, *c),
        _ => {
            return Err(PyValueError::new_err(format!("an image is a (H, W) or (H, W, C) array, got shape {shape:?}")))
        }
    };
    let names = match (names, c) {
        (Some(n), _) => n,
        (None, 3) => vec!["R".into(), "G".into(), "B".into()],
        (None, 1) => vec!["Y".into()],
        (None, _) => return Err(PyValueError::new_err(format!("a (H, W, {c}) array needs its {c} channel names"))),
    };
    if names.len() != c {
        return Err(PyValueError::new_err(format!("{} channel names for an array of {c} channels", names.len())));
    }
    let data = view.as_slice().map_err(|e| PyValueError::new_err(e.to_string()))?.to_vec();
    Image::from_data(w as u32, h as u32, names, data).map_err(|e| PyValueError::new_err(e.to_string()))
}

/// A `Render` as one image: R, G, B, then its other channels in name order.
pub fn render_image(r: &Render, py: Python<'_>) -> PyResult<Image> {
    let rgb = r.image.bind(py);
    let mut img = array_image(rgb.as_any(), None)?;
    let channels = r.channels.bind(py);
    if channels.is_empty() {
        return Ok(img);
    }
    let mut names: Vec<String> = channels.keys().extract()?;
    names.sort();
    let planes: Vec<Image> = names
        .iter()
        .map(|n| array_image(&channels.as_any().get_item(n)?, Some(vec![n.clone()])))
        .collect::<PyResult<_>>()?;
    let nc = 3 + names.len();
    let mut data = Vec::with_capacity(img.npixels() * nc);
    for i in 0..img.npixels() {
        data.extend_from_slice(&img.data[3 * i..3 * i + 3]);
        data.extend(planes.iter().map(|p| p.data[i]));
    }
    let mut all = img.channels.clone();
    all.extend(names);
    img = Image::from_data(img.width, img.height, all, data).map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(img)
}

/// An image argument: a path (read as the CLI reads it), a `Render`, or an array; and its
/// samples per pixel when known (a render's, or the `stats.json` beside a file).
pub fn image_of(obj: &Bound<'_, PyAny>) -> PyResult<(Image, Option<f64>)> {
    if let Ok(r) = obj.cast::<Render>() {
        let r = r.get();
        return Ok((render_image(r, obj.py())?, Some(r.spp as f64)));
    }
    if let Ok(p) = obj.extract::<PathBuf>() {
        let img = image::read(&p).map_err(|e| PyIOError::new_err(format!("{}: {e}", p.display())))?;
        return Ok((img, penumbra_cli::check::spp_from_stats(&p)));
    }
    Ok((array_image(obj, None)?, None))
}

/// Reads an EXR, PNG or PFM file as the CLI does.
///
/// Returns a float32 array of shape (H, W, len(channels)) with the named channels (default
/// R, G, B); a missing channel raises ValueError naming the file's channels. PNGs read as
/// their code values v/255 (not linearised), as `penumbra diff` reads them.
#[pyfunction]
#[pyo3(signature = (path, channels=None))]
pub fn read_image<'py>(py: Python<'py>, path: PathBuf, channels: Option<Vec<String>>) -> PyResult<Bound<'py, PyAny>> {
    let img = image::read(&path).map_err(|e| PyIOError::new_err(format!("{}: {e}", path.display())))?;
    let names = channels.unwrap_or_else(|| vec!["R".into(), "G".into(), "B".into()]);
    let sel = img.select_channels(&names).map_err(|e| {
        PyValueError::new_err(format!("{}: {e} (its channels: {})", path.display(), img.channels.join(", ")))
    })?;
    let (w, h, c) = (sel.width as usize, sel.height as usize, names.len());
    let a = Array3::from_shape_vec((h, w, c), sel.data).map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok(PyArray3::from_owned_array(py, a).into_any())
}

/// Writes an image as the CLI does (the format follows the extension: .exr float32 with every
/// channel, .png sRGB 8-bit with `exposure` stops, .pfm R, G, B).
///
/// `image` is a `Render` (all its channels), a (H, W, 3) array, or a (H, W, C) array with
/// `channels` naming its C channels. Written atomically: a failed write leaves no file.
#[pyfunction]
#[pyo3(signature = (path, image, channels=None, exposure=0.0))]
pub fn write_image(
    path: PathBuf,
    image: &Bound<'_, PyAny>,
    channels: Option<Vec<String>>,
    exposure: f32,
) -> PyResult<()> {
    let mut img = match image.cast::<Render>() {
        Ok(r) => render_image(r.get(), image.py())?,
        Err(_) => array_image(image, channels)?,
    };
    let ext = |e: &str| path.extension().is_some_and(|x| x.eq_ignore_ascii_case(e));
    if !ext("exr") && img.channels.len() > 3 && img.rgb_indices().is_some() {
        img = img.select_channels(&["R", "G", "B"]).map_err(|e| PyValueError::new_err(e.to_string()))?;
    }
    let io = |e: penumbra_core::image::ImageError| PyIOError::new_err(format!("{}: {e}", path.display()));
    if ext("png") {
        image::write_png(&img, &path, exposure).map_err(io)
    } else {
        image::write(&img, &path).map_err(io)
    }
}
