//! Choosing a file to open or to write: the desktop's dialog when one answers, else an in-app
//! dialog drawn with egui (a folder listing and a path field).
//!
//! The desktop dialog is `rfd` through the xdg desktop portal (D-Bus). Without a portal (a bare
//! X server, a minimal desktop) rfd returns `None` at once, the same answer as a user's Cancel;
//! an answer faster than a person can cancel ([`PORTAL_FAILED_BELOW`]) is taken as "no portal",
//! and the in-app dialog opens instead with a one-line note. Without a D-Bus session bus it
//! opens directly.
//!
//! ```text
//!  choose(purpose) ─ bus? ─ yes ─► "radlab-file-dialog" thread: rfd ─► Some(path) ─► chosen
//!                      │                                           └─ None, fast ─┐
//!                      └─ no ────────────────────────────────────────────────────► InAppDialog
//! ```

use eframe::egui;
use std::path::{Path, PathBuf};
use std::sync::mpsc::{Receiver, channel};
use std::time::{Duration, Instant};

/// A desktop dialog answering "nothing chosen" sooner than this did not open (no portal).
pub const PORTAL_FAILED_BELOW: Duration = Duration::from_millis(400);

/// What a file is chosen for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Purpose {
    /// A scene to open (.gltf/.glb).
    Open,
    /// Where to write the baked solution (.glb/.gltf); the suggested file name, and the size of
    /// the lightmap to bake (`None`: vertex colours per element, [`crate::present::bake::BakeForm`]).
    ExportBake { suggested: String, lightmap: Option<u32> },
}

impl Purpose {
    fn title(&self) -> &'static str {
        match self {
            Purpose::Open => "Open a glTF scene",
            Purpose::ExportBake { .. } => "Export baked glTF",
        }
    }

    fn action(&self) -> &'static str {
        match self {
            Purpose::Open => "Open",
            Purpose::ExportBake { .. } => "Export",
        }
    }
}

/// What the user did with a dialog.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Answer {
    Chosen(Purpose, PathBuf),
    Cancelled(Purpose),
    /// The desktop dialog failed; the in-app dialog is now open. The note says why (one line).
    FellBack(String),
}

/// True if a D-Bus session bus (which the xdg portal needs) can be reached.
#[must_use]
pub fn session_bus_available() -> bool {
    std::env::var_os("DBUS_SESSION_BUS_ADDRESS").is_some_and(|v| !v.is_empty())
        || std::env::var_os("XDG_RUNTIME_DIR").is_some_and(|d| Path::new(&d).join("bus").exists())
}

/// True if the desktop dialog's "nothing chosen" came too fast to be a person's Cancel.
#[must_use]
pub fn portal_failed(answer: Option<&Path>, after: Duration) -> bool {
    answer.is_none() && after < PORTAL_FAILED_BELOW
}

/// The file dialogs of one window: at most one open at a time.
pub struct FileDialogs {
    /// Try the desktop dialog first (tests turn it off: they must not depend on a portal).
    pub use_desktop: bool,
    desktop: Option<(Purpose, Receiver<Option<PathBuf>>, Instant)>,
    in_app: Option<InAppDialog>,
}

impl FileDialogs {
    #[must_use]
    pub fn new(use_desktop: bool) -> FileDialogs {
        FileDialogs { use_desktop, desktop: None, in_app: None }
    }

    /// True while a dialog is open.
    #[must_use]
    pub fn is_open(&self) -> bool {
        self.desktop.is_some() || self.in_app.is_some()
    }

    /// Open a dialog for `purpose` (ignored while one is open).
    pub fn choose(&mut self, purpose: Purpose) {
        if self.is_open() {
            return;
        }
        if self.use_desktop && session_bus_available() {
            let (tx, rx) = channel();
            let p = purpose.clone();
            let spawned = std::thread::Builder::new().name("radlab-file-dialog".into()).spawn(move || {
                let _ = tx.send(desktop_dialog(&p));
            });
            if spawned.is_ok() {
                self.desktop = Some((purpose, rx, Instant::now()));
                return;
            }
        }
        let note = self.use_desktop.then(|| "no desktop session bus: the built-in dialog".to_owned());
        self.in_app = Some(InAppDialog::new(purpose, note));
    }

    /// Poll the desktop dialog and draw the in-app one; returns what the user did, if anything.
    pub fn show(&mut self, ctx: &egui::Context) -> Option<Answer> {
        if let Some((purpose, rx, since)) = &self.desktop {
            match rx.try_recv() {
                Ok(Some(path)) => {
                    let purpose = purpose.clone();
                    self.desktop = None;
                    return Some(Answer::Chosen(purpose, path));
                }
                Ok(None) if portal_failed(None, since.elapsed()) => {
                    let note = "the desktop file dialog did not open (no xdg portal?): the built-in dialog";
                    self.in_app = Some(InAppDialog::new(purpose.clone(), Some(note.to_owned())));
                    self.desktop = None;
                    return Some(Answer::FellBack(note.to_owned()));
                }
                Ok(None) | Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                    let purpose = purpose.clone();
                    self.desktop = None;
                    return Some(Answer::Cancelled(purpose));
                }
                Err(std::sync::mpsc::TryRecvError::Empty) => {
                    ctx.request_repaint_after(Duration::from_millis(100));
                }
            }
        }
        let dialog = self.in_app.as_mut()?;
        let answer = dialog.ui(ctx)?;
        self.in_app = None;
        Some(answer)
    }
}

/// The desktop's dialog (blocks; runs on its own thread).
fn desktop_dialog(purpose: &Purpose) -> Option<PathBuf> {
    let d = rfd::FileDialog::new();
    match purpose {
        Purpose::Open => d.add_filter("glTF", &["gltf", "glb"]).pick_file(),
        Purpose::ExportBake { suggested, .. } => d
            .add_filter("glTF binary", &["glb"])
            .add_filter("glTF JSON", &["gltf"])
            .set_file_name(suggested)
            .save_file(),
    }
}

/// One entry of the in-app dialog's listing.
#[derive(Clone, Debug)]
struct Entry {
    name: String,
    dir: bool,
}

/// The in-app dialog: a folder listing (folders and glTF files) and a path field.
pub struct InAppDialog {
    purpose: Purpose,
    folder: PathBuf,
    entries: Result<Vec<Entry>, String>,
    /// The path typed or clicked: absolute, or relative to `folder`.
    path: String,
    note: Option<String>,
    error: Option<String>,
}

impl InAppDialog {
    fn new(purpose: Purpose, note: Option<String>) -> InAppDialog {
        let folder = std::env::current_dir().unwrap_or_else(|_| PathBuf::from("/"));
        let mut d =
            InAppDialog { purpose, entries: Ok(Vec::new()), folder, path: String::new(), note, error: None };
        d.list();
        d
    }

    fn list(&mut self) {
        self.entries = std::fs::read_dir(&self.folder)
            .map_err(|e| format!("{}: {e}", self.folder.display()))
            .map(|rd| {
                let mut v: Vec<Entry> = rd
                    .filter_map(Result::ok)
                    .filter_map(|e| {
                        let name = e.file_name().to_string_lossy().into_owned();
                        let dir = e.path().is_dir();
                        (!name.starts_with('.') && (dir || is_gltf(Path::new(&name))))
                            .then_some(Entry { name, dir })
                    })
                    .collect();
                v.sort_by(|a, b| b.dir.cmp(&a.dir).then_with(|| a.name.cmp(&b.name)));
                v
            });
    }

    fn enter(&mut self, folder: PathBuf) {
        self.folder = folder;
        self.error = None;
        self.list();
    }

    /// The chosen path, or why it cannot be used (one line).
    fn resolve(&self) -> Result<PathBuf, String> {
        let typed = match (&self.purpose, self.path.trim()) {
            (Purpose::ExportBake { suggested, .. }, "") => suggested.as_str(),
            (_, "") => return Err("type a file name or click a file".into()),
            (_, t) => t,
        };
        let p = self.folder.join(typed);
        if !is_gltf(&p) {
            return Err(format!("{}: not a .gltf/.glb file", p.display()));
        }
        match self.purpose {
            Purpose::Open if !p.is_file() => Err(format!("{}: no such file", p.display())),
            Purpose::ExportBake { .. } if p.parent().is_some_and(|f| !f.is_dir()) => {
                Err(format!("{}: the folder does not exist", p.display()))
            }
            _ => Ok(p),
        }
    }

    /// Draw the dialog; `Some` once the user chose a file or cancelled.
    fn ui(&mut self, ctx: &egui::Context) -> Option<Answer> {
        let mut answer = None;
        let mut open = true;
        egui::Window::new(self.purpose.title())
            .open(&mut open)
            .collapsible(false)
            .resizable(false)
            .fixed_size([460.0, 340.0])
            .anchor(egui::Align2::CENTER_CENTER, [0.0, 0.0])
            .show(ctx, |ui| {
                if let Some(n) = &self.note {
                    ui.weak(n);
                }
                if let Purpose::ExportBake { lightmap: Some(size), .. } = self.purpose {
                    ui.weak(format!("the original meshes with a {size}×{size} lightmap"));
                }
                ui.horizontal(|ui| {
                    if ui.button("Up").on_hover_text("The parent folder").clicked()
                        && let Some(parent) = self.folder.parent()
                    {
                        self.enter(parent.to_path_buf());
                    }
                    ui.monospace(self.folder.display().to_string());
                });
                let mut go = None;
                egui::ScrollArea::vertical()
                    .id_salt("file_list")
                    .max_height(200.0)
                    .min_scrolled_height(200.0)
                    .show(ui, |ui| {
                        ui.set_min_width(440.0);
                        match &self.entries {
                            Err(e) => {
                                ui.colored_label(egui::Color32::from_rgb(255, 150, 130), e);
                            }
                            Ok(v) if v.is_empty() => {
                                ui.weak("(no folders or .gltf/.glb files here)");
                            }
                            Ok(v) => {
                                for e in v {
                                    let label = if e.dir { format!("{}/", e.name) } else { e.name.clone() };
                                    let tip = if e.dir { "Open this folder" } else { "Choose this file" };
                                    if ui
                                        .selectable_label(!e.dir && self.path == e.name, label)
                                        .on_hover_text(tip)
                                        .clicked()
                                    {
                                        go = Some(e.clone());
                                    }
                                }
                            }
                        }
                    });
                if let Some(e) = go {
                    if e.dir {
                        self.enter(self.folder.join(&e.name));
                    } else {
                        self.path = e.name;
                        self.error = None;
                    }
                }
                let hint = match &self.purpose {
                    Purpose::Open => "file name, or a path".to_owned(),
                    Purpose::ExportBake { suggested, .. } => suggested.clone(),
                };
                let field = ui
                    .add(
                        egui::TextEdit::singleline(&mut self.path)
                            .desired_width(f32::INFINITY)
                            .hint_text(hint),
                    )
                    .on_hover_text("A file name in the folder above, or a path");
                ui.ctx().accesskit_node_builder(field.id, |b| b.set_label("file path"));
                let enter = field.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
                // One reserved line: the dialog does not change size when an error shows.
                let msg = self.error.clone().unwrap_or_default();
                ui.add(
                    egui::Label::new(egui::RichText::new(msg).color(egui::Color32::from_rgb(255, 150, 130)))
                        .truncate(),
                );
                ui.horizontal(|ui| {
                    let act = ui.button(self.purpose.action()).on_hover_text("Use the path typed above");
                    if act.clicked() || enter {
                        match self.resolve() {
                            Ok(p) => answer = Some(Answer::Chosen(self.purpose.clone(), p)),
                            Err(e) => self.error = Some(e),
                        }
                    }
                    if ui.button("Cancel").on_hover_text("Close without choosing a file").clicked() {
                        answer = Some(Answer::Cancelled(self.purpose.clone()));
                    }
                });
            });
        if !open {
            answer = Some(Answer::Cancelled(self.purpose.clone()));
        }
        answer
    }
}

/// `.gltf` or `.glb`, any case.
#[must_use]
pub fn is_gltf(p: &Path) -> bool {
    p.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fast_empty_answer_means_no_portal() {
        assert!(portal_failed(None, Duration::from_millis(5)));
        assert!(!portal_failed(None, Duration::from_secs(3)), "a person's Cancel");
        assert!(!portal_failed(Some(Path::new("a.glb")), Duration::from_millis(5)));
    }

    #[test]
    fn the_in_app_dialog_refuses_what_it_cannot_use() {
        let mut d = InAppDialog::new(Purpose::Open, None);
        d.folder = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
        d.path = "parallel.gltf".into();
        assert!(d.resolve().is_ok());
        d.path = "no-such.glb".into();
        assert!(d.resolve().unwrap_err().contains("no such file"));
        d.path = "../fonts/LICENSE-DejaVu.txt".into();
        assert!(d.resolve().unwrap_err().contains("not a .gltf/.glb file"));
        let mut e = InAppDialog::new(Purpose::ExportBake { suggested: "x.glb".into(), lightmap: None }, None);
        e.folder = std::env::temp_dir();
        assert!(e.resolve().is_ok(), "a new file in an existing folder");
        e.path = "no-such-folder/x.glb".into();
        assert!(e.resolve().unwrap_err().contains("folder does not exist"));
    }
}
