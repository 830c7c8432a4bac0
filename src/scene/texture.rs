//! Base-colour textures of imported glTF, averaged into each triangle's reflectance.
//!
//! A glTF material's diffuse colour is `baseColorFactor × texel(uv)` [glTF 2.0, sec. 3.9.2], the
//! texel in sRGB (decoded to linear here). Radiosity needs one reflectance per patch, so each
//! triangle gets the mean of the texture over it, estimated from `SAMPLE_LEVELS²` stratified
//! samples: the centroids of the triangle's sub-triangles after splitting each edge into
//! `SAMPLE_LEVELS` parts (nearest texel, the sampler's wrap modes). The work is bounded per
//! triangle, whatever the texture's size:
//!
//! ```text
//!        uv2                 n = 4: 16 sub-triangles, one sample at each centroid
//!        /\                  (10 pointing up, 6 down), all strictly inside the triangle
//!       /··\
//!      /\··/\
//!    uv0 ──── uv1
//! ```
//!
//! Decoding is bounded too: PNG and JPEG only (the `image` crate with only those codecs), the
//! size read from the header and refused above [`MAX_SIDE`] or `max_pixels` before any pixel is
//! decoded, and the decoder given the same limits.

use crate::math::Rgb;

/// Textures wider or taller than this are refused.
pub const MAX_SIDE: u32 = 8192;

/// Each triangle's edges are split into this many parts; the texture is sampled at the
/// centroids of the `SAMPLE_LEVELS²` sub-triangles.
pub const SAMPLE_LEVELS: usize = 4;

/// How texture coordinates outside [0, 1] map into the image [glTF 2.0, sec. 5.26].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wrap {
    Repeat,
    Clamp,
    Mirror,
}

impl Wrap {
    /// The wrap mode of a glTF sampler's `wrapS`/`wrapT` value (10497 repeat, the default).
    pub fn from_gl(code: u32) -> Wrap {
        match code {
            33071 => Wrap::Clamp,
            33648 => Wrap::Mirror,
            _ => Wrap::Repeat,
        }
    }

    /// `t` mapped into [0, 1]; non-finite coordinates map to 0.
    fn apply(self, t: f64) -> f64 {
        if !t.is_finite() {
            return 0.0;
        }
        match self {
            Wrap::Repeat => t - t.floor(),
            Wrap::Clamp => t.clamp(0.0, 1.0),
            Wrap::Mirror => {
                let m = t.rem_euclid(2.0);
                if m > 1.0 { 2.0 - m } else { m }
            }
        }
    }
}

/// A decoded texture: 8-bit sRGB texels (3 bytes each, row 0 at the top: glTF's uv (0, 0) is
/// the image's top-left corner), turned linear through a table as they are sampled.
pub struct Texture {
    width: usize,
    height: usize,
    texels: Vec<u8>,
    linear: [f32; 256],
}

/// sRGB transfer function inverse (IEC 61966-2-1).
fn srgb_to_linear(c: f64) -> f64 {
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

/// The linear value of each 8-bit sRGB level.
fn linear_table() -> [f32; 256] {
    std::array::from_fn(|b| srgb_to_linear(b as f64 / 255.0) as f32)
}

/// A reader for PNG or JPEG bytes (the format guessed from them); an error for any other.
fn image_reader(bytes: &[u8]) -> Result<image::ImageReader<std::io::Cursor<&[u8]>>, String> {
    use image::{ImageFormat, ImageReader};
    let r = ImageReader::new(std::io::Cursor::new(bytes))
        .with_guessed_format()
        .map_err(|e| format!("cannot read the image: {}", one_line(&e)))?;
    match r.format() {
        Some(ImageFormat::Png | ImageFormat::Jpeg) => Ok(r),
        Some(f) => Err(format!("{f:?} images are not supported (PNG and JPEG are)")),
        None => Err("not a PNG or JPEG image".into()),
    }
}

impl Texture {
    /// The width and height a PNG or JPEG header declares, read without decoding a pixel;
    /// an error (one line, without the file name) for another format, a bad header, an empty
    /// image, or one above [`MAX_SIDE`] on a side or above `max_pixels` in all.
    pub fn header(bytes: &[u8], max_pixels: u64) -> Result<(u32, u32), String> {
        let (w, h) = image_reader(bytes)?
            .into_dimensions()
            .map_err(|e| format!("bad image header: {}", one_line(&e)))?;
        let pixels = u64::from(w) * u64::from(h);
        if w > MAX_SIDE || h > MAX_SIDE || pixels > max_pixels {
            return Err(format!(
                "image is {w}×{h}, more than the limit of {MAX_SIDE}×{MAX_SIDE} and {max_pixels} pixels"
            ));
        }
        if pixels == 0 {
            return Err("image is empty (0 pixels)".into());
        }
        Ok((w, h))
    }

    /// Decode PNG or JPEG bytes, refusing images above [`MAX_SIDE`] on a side or above
    /// `max_pixels` in all before decoding them ([`Texture::header`]). The error is one line
    /// without the file name.
    pub fn decode(bytes: &[u8], max_pixels: u64) -> Result<Texture, String> {
        let (w, h) = Texture::header(bytes, max_pixels)?;
        let pixels = u64::from(w) * u64::from(h);
        let mut r = image_reader(bytes)?;
        let mut limits = image::Limits::default();
        limits.max_image_width = Some(MAX_SIDE);
        limits.max_image_height = Some(MAX_SIDE);
        // RGBA at 16 bits per channel, plus the 8-bit RGB copy.
        limits.max_alloc = Some(pixels.saturating_mul(8 + 3).max(1 << 20));
        r.limits(limits);
        let rgb = r.decode().map_err(|e| format!("cannot decode the image: {}", one_line(&e)))?.into_rgb8();
        let (width, height) = (rgb.width() as usize, rgb.height() as usize);
        Ok(Texture { width, height, texels: rgb.into_raw(), linear: linear_table() })
    }

    /// Width and height in texels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The nearest texel to `uv` (linear RGB).
    pub fn sample(&self, uv: [f64; 2], wrap: [Wrap; 2]) -> Rgb {
        let u = wrap[0].apply(uv[0]);
        let v = wrap[1].apply(uv[1]);
        let x = ((u * self.width as f64) as usize).min(self.width - 1);
        let y = ((v * self.height as f64) as usize).min(self.height - 1);
        let i = 3 * (y * self.width + x);
        let t = &self.texels[i..i + 3];
        Rgb::new(
            f64::from(self.linear[t[0] as usize]),
            f64::from(self.linear[t[1] as usize]),
            f64::from(self.linear[t[2] as usize]),
        )
    }

    /// The texture's mean over the triangle with these texture coordinates (see the module doc).
    pub fn triangle_mean(&self, uv: [[f64; 2]; 3], wrap: [Wrap; 2]) -> Rgb {
        let n = SAMPLE_LEVELS;
        let nf = n as f64;
        let at = |a: f64, b: f64| {
            let c = 1.0 - a - b;
            [0, 1].map(|k| c * uv[0][k] + a * uv[1][k] + b * uv[2][k])
        };
        let mut sum = Rgb::ZERO;
        for i in 0..n {
            for j in 0..n - i {
                let (fi, fj) = (i as f64, j as f64);
                sum += self.sample(at((fi + 1.0 / 3.0) / nf, (fj + 1.0 / 3.0) / nf), wrap);
                if i + j + 1 < n {
                    sum += self.sample(at((fi + 2.0 / 3.0) / nf, (fj + 2.0 / 3.0) / nf), wrap);
                }
            }
        }
        sum / (n * n) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn checker() -> Texture {
        // 2×1: left texel red (linear 1.0), right texel black.
        Texture { width: 2, height: 1, texels: vec![255, 0, 0, 0, 0, 0], linear: linear_table() }
    }

    #[test]
    fn wrap_modes_map_into_the_unit_interval() {
        assert!((Wrap::Repeat.apply(1.25) - 0.25).abs() < 1e-12);
        assert!((Wrap::Repeat.apply(-0.25) - 0.75).abs() < 1e-12);
        assert_eq!(Wrap::Clamp.apply(3.0), 1.0);
        assert!((Wrap::Mirror.apply(1.25) - 0.75).abs() < 1e-12);
        assert_eq!(Wrap::Repeat.apply(f64::NAN), 0.0);
    }

    #[test]
    fn triangle_mean_takes_n_squared_samples_inside_the_triangle() {
        let t = checker();
        let w = [Wrap::Repeat; 2];
        // A triangle inside the left half sees only red.
        let left = t.triangle_mean([[0.0, 0.0], [0.5, 0.0], [0.0, 1.0]], w);
        assert_eq!(left.0, [1.0, 0.0, 0.0]);
        // A triangle covering both halves symmetrically: the mean is between.
        let both = t.triangle_mean([[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]], w);
        assert!(both.0[0] > 0.3 && both.0[0] < 0.7, "{both:?}");
    }

    #[test]
    fn srgb_decoding_matches_the_standard() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-12);
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-5);
    }

    #[test]
    fn refuses_what_is_not_png_or_jpeg() {
        assert!(Texture::decode(b"GIF89a\x01\x00\x01\x00", 1 << 20).is_err());
        assert!(Texture::decode(b"", 1 << 20).is_err());
    }
}

/// A decoder's message on one line (the `image` crate's errors can span several: a JPEG's
/// "Format error …\nI/O errors …"), whitespace runs collapsed to one space.
fn one_line(e: &dyn std::fmt::Display) -> String {
    e.to_string().split_whitespace().collect::<Vec<_>>().join(" ")
}

#[cfg(test)]
mod one_line_tests {
    /// Found by fuzzing: a truncated JPEG's decoder error spans two lines.
    #[test]
    fn decoder_messages_become_one_line() {
        assert_eq!(
            super::one_line(&"Format error decoding Jpeg:\n  I/O errors  Not enough bytes"),
            "Format error decoding Jpeg: I/O errors Not enough bytes"
        );
    }
}
