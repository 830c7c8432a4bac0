//! The loader's bounded, sandboxed input: regular files only (a FIFO would block, a device never
//! end), read up to a byte limit through a non-blocking read-only handle; URIs that are `data:`
//! (base64) or relative paths staying inside the scene's folder, symbolic links included; GLB
//! containers split into their JSON and BIN chunks [glTF 2.0, sec. 4.4], every length checked
//! before a byte is read; buffers whose declared lengths are summed and capped first.

use super::{Loader, SceneError};
use base64::Engine as _;
use std::borrow::Cow;
use std::io::Read;
use std::path::{Component, Path, PathBuf};

/// Why [`read_regular`] refused or failed.
pub(super) enum ReadError {
    Io(std::io::Error),
    /// What the path is instead of a regular file ("a FIFO", "a character device", …).
    NotRegular(&'static str),
    /// The file's size in bytes, above the limit.
    TooLarge(u64),
}

/// What a non-regular file is, for the error message.
fn file_kind(ft: std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt as _;
        if ft.is_fifo() {
            return "a FIFO";
        }
        if ft.is_char_device() {
            return "a character device";
        }
        if ft.is_block_device() {
            return "a block device";
        }
        if ft.is_socket() {
            return "a socket";
        }
    }
    if ft.is_dir() { "a folder" } else { "not a regular file" }
}

/// Read a regular file of at most `max_bytes` bytes (at most `want` of them, if given).
///
/// A FIFO, device, socket or folder is refused before it is opened: opening a FIFO blocks until
/// a writer comes, and a device such as `/dev/zero` never ends. The file is then opened read-only
/// and non-blocking (so a FIFO swapped in after the check cannot block either), checked again
/// through the open handle, and read through `take`, so the allocation is bounded by the limit
/// even if the file grows meanwhile.
pub(super) fn read_regular(path: &Path, max_bytes: u64, want: Option<u64>) -> Result<Vec<u8>, ReadError> {
    let check = |meta: &std::fs::Metadata| -> Result<u64, ReadError> {
        if !meta.is_file() {
            return Err(ReadError::NotRegular(file_kind(meta.file_type())));
        }
        if meta.len() > max_bytes {
            return Err(ReadError::TooLarge(meta.len()));
        }
        Ok(meta.len())
    };
    check(&std::fs::metadata(path).map_err(ReadError::Io)?)?;
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt as _;
        options.custom_flags(libc::O_NONBLOCK);
    }
    let file = options.open(path).map_err(ReadError::Io)?;
    let len = check(&file.metadata().map_err(ReadError::Io)?)?;
    let limit = want.map_or(max_bytes.saturating_add(1), |w| w.min(max_bytes.saturating_add(1)));
    let mut data = Vec::with_capacity(len.min(limit) as usize);
    file.take(limit).read_to_end(&mut data).map_err(ReadError::Io)?;
    if data.len() as u64 > max_bytes {
        return Err(ReadError::TooLarge(data.len() as u64));
    }
    Ok(data)
}

impl Loader<'_> {
    /// Split a GLB container into its JSON chunk and optional BIN chunk [glTF 2.0, sec. 4.4].
    pub(super) fn split_glb<'b>(&self, bytes: &'b [u8]) -> Result<(&'b [u8], Option<&'b [u8]>), SceneError> {
        fn u32_at(bytes: &[u8], at: usize) -> Option<u32> {
            bytes.get(at..at.checked_add(4)?).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        }
        let truncated = |what: &str| self.invalid(format!("truncated GLB: {what}"));
        let version = u32_at(bytes, 4).ok_or_else(|| truncated("header"))?;
        if version != 2 {
            return Err(self.invalid(format!("GLB version {version} (only 2 is supported)")));
        }
        let total = u32_at(bytes, 8).ok_or_else(|| truncated("header"))? as usize;
        if total > bytes.len() {
            return Err(truncated(&format!("header says {total} bytes, file has {}", bytes.len())));
        }
        if total < 12 {
            return Err(self.invalid(format!("GLB header says {total} bytes, less than the header itself")));
        }
        let bytes = &bytes[..total];
        let chunk = |at: usize| -> Result<Option<(&'b [u8], u32)>, SceneError> {
            if at >= bytes.len() {
                return Ok(None);
            }
            let len = u32_at(bytes, at).ok_or_else(|| truncated("chunk header"))? as usize;
            let ty = u32_at(bytes, at + 4).ok_or_else(|| truncated("chunk header"))?;
            let data = at
                .checked_add(8)
                .and_then(|s| s.checked_add(len).map(|e| (s, e)))
                .and_then(|(s, e)| bytes.get(s..e))
                .ok_or_else(|| truncated(&format!("chunk at byte {at} claims {len} bytes")))?;
            Ok(Some((data, ty)))
        };
        const JSON: u32 = 0x4E4F_534A;
        const BIN: u32 = 0x004E_4942;
        let (json, ty) = chunk(12)?.ok_or_else(|| truncated("no JSON chunk"))?;
        if ty != JSON {
            return Err(self.invalid("GLB's first chunk is not JSON"));
        }
        let next = 12 + 8 + json.len().next_multiple_of(4);
        let bin = match chunk(next)? {
            Some((data, BIN)) => Some(data),
            _ => None,
        };
        Ok((json, bin))
    }

    /// Resolve a URI to a file inside the scene's folder, or reject it.
    pub(super) fn check_uri(&self, uri: &str) -> Result<Option<PathBuf>, SceneError> {
        let reject = || SceneError::UriOutsideScene { file: self.file.clone(), uri: uri.to_string() };
        if uri.starts_with("data:") {
            return Ok(None);
        }
        let decoded = percent_decode(uri).ok_or_else(reject)?;
        // A scheme (`http:`, `file:`, a drive letter `C:`) appears before the first separator.
        let first_sep = decoded.find(['/', '\\']).unwrap_or(decoded.len());
        if decoded[..first_sep].contains(':') || decoded.contains('\0') {
            return Err(reject());
        }
        let rel = Path::new(&decoded);
        let mut depth = 0usize;
        for comp in decoded.split(['/', '\\']) {
            match comp {
                "" if depth == 0 && decoded.starts_with(['/', '\\']) => return Err(reject()),
                "" | "." => {}
                ".." => depth = depth.checked_sub(1).ok_or_else(reject)?,
                _ => depth += 1,
            }
        }
        if rel.is_absolute()
            || rel.components().any(|c| matches!(c, Component::Prefix(_) | Component::RootDir))
        {
            return Err(reject());
        }
        Ok(Some(PathBuf::from(decoded.replace('\\', "/"))))
    }

    /// Read every buffer: data URIs, relative files, or the GLB binary chunk (borrowed, not
    /// copied: however many buffers name it, it is in memory once). The declared byteLengths are
    /// summed and capped by [`LoadOptions::max_file_bytes`] before any buffer is read.
    pub(super) fn read_buffers<'b>(
        &self,
        doc: &gltf::Document,
        blob: Option<&'b [u8]>,
    ) -> Result<Vec<Cow<'b, [u8]>>, SceneError> {
        let declared = doc.buffers().fold(0u64, |sum, b| sum.saturating_add(b.length() as u64));
        if declared > self.opts.max_file_bytes {
            return Err(self.invalid(format!(
                "buffers declare {declared} bytes in all, more than the {} byte limit",
                self.opts.max_file_bytes
            )));
        }
        let mut out = Vec::new();
        for buf in doc.buffers() {
            let index = buf.index();
            let err = |cause: String| SceneError::Buffer { file: self.file.clone(), index, cause };
            let want = buf.length();
            let data = match buf.source() {
                gltf::buffer::Source::Bin => {
                    Cow::Borrowed(blob.ok_or_else(|| err("no GLB binary chunk and no uri".into()))?)
                }
                gltf::buffer::Source::Uri(uri) => match self.check_uri(uri)? {
                    None => Cow::Owned(decode_data_uri(uri).map_err(err)?),
                    Some(rel) => Cow::Owned(self.read_relative(&rel, uri, want).map_err(err)?),
                },
            };
            if data.len() < want {
                return Err(err(format!("has {} bytes, byteLength says {want}", data.len())));
            }
            out.push(data);
        }
        Ok(out)
    }

    /// The file a relative URI names, if it stays inside the scene's folder (symbolic links
    /// included).
    fn resolve(&self, rel: &Path, uri: &str) -> Result<PathBuf, String> {
        let base = self.base_dir.ok_or_else(|| format!("{uri:?}: no folder to resolve a relative URI in"))?;
        let path = base.join(rel);
        let canon_base = base.canonicalize().map_err(|e| format!("{}: {e}", base.display()))?;
        let canon = path.canonicalize().map_err(|e| format!("{}: {e}", path.display()))?;
        if !canon.starts_with(&canon_base) {
            return Err(format!("{uri:?} resolves outside the scene's folder"));
        }
        Ok(canon)
    }

    /// Read at most `want` bytes (the buffer's byteLength) of a regular file inside the folder.
    pub(super) fn read_relative(&self, rel: &Path, uri: &str, want: usize) -> Result<Vec<u8>, String> {
        let canon = self.resolve(rel, uri)?;
        let shown = self.base_dir.map_or_else(|| rel.to_path_buf(), |b| b.join(rel));
        read_regular(&canon, self.opts.max_file_bytes, Some(want as u64)).map_err(|e| match e {
            ReadError::Io(e) => format!("{}: {e}", shown.display()),
            ReadError::NotRegular(kind) => format!("{} is {kind}, not a regular file", shown.display()),
            ReadError::TooLarge(len) => format!(
                "{} has {len} bytes, more than the {} byte limit",
                shown.display(),
                self.opts.max_file_bytes
            ),
        })
    }

    /// Every image file that exists must be a regular file inside the folder, as a buffer must
    /// (used as a texture or not): a FIFO or device is refused here, before anything could open
    /// it. A missing image is a warning (materials using it keep their factor).
    pub(super) fn check_image_file(&mut self, index: usize, rel: &Path, uri: &str) -> Result<(), SceneError> {
        let Some(base) = self.base_dir else { return Ok(()) };
        let shown = base.join(rel);
        if std::fs::metadata(&shown).is_err_and(|e| e.kind() == std::io::ErrorKind::NotFound) {
            self.warnings
                .push(format!("image {index}: {} not found (its texture is not used)", shown.display()));
            return Ok(());
        }
        let err = |cause: String| SceneError::Image { file: self.file.clone(), index, cause };
        let canon = self.resolve(rel, uri).map_err(err)?;
        let meta = std::fs::metadata(&canon).map_err(|e| err(format!("{}: {e}", shown.display())))?;
        if !meta.is_file() {
            return Err(err(format!(
                "{} is {}, not a regular file",
                shown.display(),
                file_kind(meta.file_type())
            )));
        }
        Ok(())
    }
}

/// Decode `%XX` escapes; `None` on a malformed escape or invalid UTF-8.
fn percent_decode(s: &str) -> Option<String> {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' {
            let hex = std::str::from_utf8(b.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(b[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// Decode `data:[<mime>];base64,<payload>`.
pub(super) fn decode_data_uri(uri: &str) -> Result<Vec<u8>, String> {
    let rest = &uri["data:".len()..];
    let (header, payload) = rest.split_once(',').ok_or("data: URI without a comma")?;
    if !header.ends_with(";base64") {
        return Err("data: URI is not base64".into());
    }
    base64::engine::general_purpose::STANDARD
        .decode(payload.trim())
        .map_err(|e| format!("bad base64 in data: URI: {e}"))
}
