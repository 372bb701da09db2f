//! Output folders (`render`, `run`, `diagnose`): built whole in a staging folder beside the
//! target and swapped in at the end, so that a run killed at any moment leaves the folder as it
//! was or complete, never a new `fitted.toml` beside a stale `report.json`.
//!
//! A key design decision made here is ownership: physfit lists every file it writes into a
//! folder in `.physfit-outputs` there. Files that are not listed (the user's) are never deleted
//! or overwritten: they are carried into the new folder (hard links, so not a byte is copied),
//! and an output that would replace one is refused, naming it, before anything changes.
//!
//! The swap is `renameat2(RENAME_EXCHANGE)` (Linux), one atomic step; where it is unavailable
//! the old folder is renamed aside and the new one into place, and a folder set aside by a
//! killed run is put back by the next one. Staging folders (`.NAME.physfit-COMMAND-PID` beside
//! the target) of processes no longer running are removed by the next run.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};

/// The list of the files physfit wrote into an output folder, one relative path a line.
pub const MANIFEST: &str = ".physfit-outputs";

/// An output folder being built: write into [`Staged::dir`], then [`Staged::commit`].
#[derive(Debug)]
pub struct Staged {
    /// The folder the user named.
    target: PathBuf,
    /// Where the new content is built, beside `target`.
    staging: PathBuf,
    /// True if and only if the working folder is `target` or inside it: the folder itself is
    /// then kept (a shell sitting in it would otherwise be left in a deleted folder) and each
    /// output is renamed into it, atomic file by file rather than as a whole.
    in_place: bool,
}

/// The parent folder and name of `target`.
fn parent_and_name(target: &Path) -> anyhow::Result<(PathBuf, String)> {
    let absolute = std::path::absolute(target).with_context(|| format!("--out {}", target.display()))?;
    let name = absolute
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .with_context(|| format!("--out {}: not a folder name", target.display()))?;
    let parent = absolute
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("/"));
    Ok((parent, name))
}

/// Returns true if and only if process `pid` is running (Linux: `/proc/PID` exists).
fn alive(pid: u32) -> bool {
    pid == std::process::id() || Path::new(&format!("/proc/{pid}")).exists()
}

/// The pid at the end of a staging folder's name `prefix...-PID`.
fn pid_of(name: &str) -> Option<u32> {
    name.rsplit('-').next()?.parse().ok()
}

/// Removes our staging folders beside `target` left by processes that are no longer running,
/// and puts back a folder a killed swap had set aside.
fn clean_stale(parent: &Path, name: &str, target: &Path) {
    let Ok(entries) = std::fs::read_dir(parent) else {
        return;
    };
    let prefix = format!(".{name}.physfit-");
    for entry in entries.flatten() {
        let file = entry.file_name().to_string_lossy().into_owned();
        let Some(rest) = file.strip_prefix(&prefix) else {
            continue;
        };
        match pid_of(rest) {
            Some(pid) if !alive(pid) => {}
            _ => continue,
        }
        if rest.starts_with("old-") && !target.exists() {
            // Killed between the two renames of a swap: the set-aside folder is the only one.
            let _ = std::fs::rename(entry.path(), target);
        } else {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
    // Staging folders inside the target, from physfit versions that staged there.
    if let Ok(entries) = std::fs::read_dir(target) {
        for entry in entries.flatten() {
            let file = entry.file_name().to_string_lossy().into_owned();
            if let Some(rest) = file.strip_prefix(".physfit-render-") {
                if pid_of(rest).is_some_and(|p| !alive(p)) {
                    let _ = std::fs::remove_dir_all(entry.path());
                }
            }
        }
    }
}

/// Removes the temporary files that writes of `path` by processes no longer running left beside
/// it (`.NAME.PID.tmp` and `.NAME.PID.SERIAL.tmp`: killed between creating and renaming them);
/// called by the commands that write one file (`simulate`, `track`, `fit`) before they write.
pub fn clean_stale_temps(path: &Path) {
    let (Some(name), dir) = (
        path.file_name(),
        path.parent().filter(|d| !d.as_os_str().is_empty()),
    ) else {
        return;
    };
    let prefix = format!(".{}.", name.to_string_lossy());
    let Ok(entries) = std::fs::read_dir(dir.unwrap_or(Path::new("."))) else {
        return;
    };
    for entry in entries.flatten() {
        let file = entry.file_name().to_string_lossy().into_owned();
        let Some(rest) = file.strip_prefix(&prefix).and_then(|r| r.strip_suffix(".tmp")) else {
            continue;
        };
        let pid = rest.split('.').next().and_then(|p| p.parse::<u32>().ok());
        if pid.is_some_and(|p| !alive(p)) && entry.path().is_file() {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// The files (relative paths, `/`-separated) under `dir`, recursively; symbolic links are
/// listed, not followed.
fn files_under(dir: &Path) -> std::io::Result<BTreeSet<String>> {
    let mut out = BTreeSet::new();
    let mut stack = vec![(dir.to_path_buf(), String::new())];
    while let Some((d, rel)) = stack.pop() {
        for entry in std::fs::read_dir(&d)? {
            let entry = entry?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let path = if rel.is_empty() {
                name
            } else {
                format!("{rel}/{name}")
            };
            if entry.file_type()?.is_dir() {
                stack.push((entry.path(), path));
            } else {
                out.insert(path);
            }
        }
    }
    Ok(out)
}

/// The files physfit listed as written into `target`; `None` without a list.
fn owned(target: &Path) -> Option<BTreeSet<String>> {
    std::fs::read_to_string(target.join(MANIFEST))
        .ok()
        .map(|t| t.lines().filter(|l| !l.is_empty()).map(str::to_string).collect())
}

/// True if and only if `target` holds the output of a physfit from before the list
/// ([`MANIFEST`]) was kept: a `report.json` of `run` or `diagnose` (an object with `base` and
/// `final`), or `render`'s `truth.csv` (header `frame,particle,x,y`) beside its `scene.toml`.
/// Its files of physfit's names are then taken as physfit's, so that the README's first
/// command, run again after an upgrade, is not refused.
fn earlier_output(target: &Path) -> bool {
    let report = std::fs::read_to_string(target.join("report.json"))
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .is_some_and(|v| v.get("base").is_some() && v.get("final").is_some());
    let render = target.join("scene.toml").is_file()
        && std::fs::read_to_string(target.join("truth.csv"))
            .is_ok_and(|t| t.starts_with("frame,particle,x,y"));
    report || render
}

/// True if and only if `file` (relative to an earlier output folder) has a name physfit gives
/// its outputs: a top-level file, a frame `frames/NNNNNN.png` or an overlay
/// `overlay/frame_NNNNNN.png`.
fn physfit_named(file: &str) -> bool {
    let numbered = |name: &str, prefix: &str| {
        name.strip_prefix(prefix)
            .and_then(|n| n.strip_suffix(".png"))
            .is_some_and(|n| n.len() == 6 && n.bytes().all(|b| b.is_ascii_digit()))
    };
    match file.split_once('/') {
        None => true,
        Some(("frames", name)) => numbered(name, ""),
        Some(("overlay", name)) => numbered(name, "frame_"),
        Some(_) => false,
    }
}

/// The files of `target` that physfit did not write and that outputs named `names` (top-level
/// entries: a file, or a folder replaced as a whole) would replace or delete.
fn in_the_way(target: &Path, names: &BTreeSet<String>) -> anyhow::Result<Vec<String>> {
    if !target.is_dir() {
        return Ok(Vec::new());
    }
    let owned = owned(target);
    let mut files = Vec::new();
    // Only the entries the outputs replace are walked: `--out` may be a large folder.
    for name in names {
        let path = target.join(name);
        match std::fs::symlink_metadata(&path) {
            Ok(meta) if meta.is_dir() => {
                let under = files_under(&path).with_context(|| format!("reading {}", path.display()))?;
                files.extend(under.into_iter().map(|f| format!("{name}/{f}")));
            }
            Ok(_) => files.push(name.clone()),
            Err(_) => {}
        }
    }
    match owned {
        Some(owned) => files.retain(|f| !owned.contains(f)),
        None if earlier_output(target) => files.retain(|f| !physfit_named(f)),
        None => {}
    }
    Ok(files)
}

/// The error for files of the user's that outputs would replace.
fn refuse(target: &Path, files: &[String]) -> anyhow::Error {
    let mut listed: Vec<String> = files
        .iter()
        .take(5)
        .map(|f| target.join(f).display().to_string())
        .collect();
    if files.len() > 5 {
        listed.push(format!("and {} more", files.len() - 5));
    }
    anyhow::anyhow!(
        "--out {}: {} not written by physfit and would be replaced: {}; nothing was changed \
         (move {} away, or choose another --out)",
        target.display(),
        if files.len() == 1 {
            "this file was"
        } else {
            "these files were"
        },
        listed.join(", "),
        if files.len() == 1 { "it" } else { "them" }
    )
}

impl Staged {
    /// Starts building the output folder `target` for `command`: refuses a `target` that is a
    /// file or read-only, or whose files of the user's the outputs `names` (top-level entries)
    /// would replace; removes stale staging folders of ours; creates the staging folder.
    pub fn begin(target: &Path, command: &str, names: &[&str]) -> anyhow::Result<Staged> {
        let (parent, name) = parent_and_name(target)?;
        if let Ok(meta) = std::fs::metadata(target) {
            if !meta.is_dir() {
                bail!("--out {}: this is a file, not a folder", target.display());
            }
            if meta.permissions().readonly() {
                bail!("--out {}: the folder is read-only", target.display());
            }
        }
        std::fs::create_dir_all(&parent)
            .with_context(|| format!("--out {}: creating {}", target.display(), parent.display()))?;
        clean_stale(&parent, &name, target);
        let names: BTreeSet<String> = names.iter().map(|s| s.to_string()).collect();
        let blocking = in_the_way(target, &names)?;
        if !blocking.is_empty() {
            return Err(refuse(target, &blocking));
        }
        let staging = parent.join(format!(".{name}.physfit-{command}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&staging);
        std::fs::create_dir(&staging).with_context(|| {
            format!(
                "--out {}: cannot create a staging folder beside it ({})",
                target.display(),
                staging.display()
            )
        })?;
        let target = parent.join(&name);
        let in_place = std::env::current_dir()
            .and_then(|d| d.canonicalize())
            .ok()
            .zip(target.canonicalize().ok())
            .is_some_and(|(cwd, t)| cwd.starts_with(t));
        Ok(Staged {
            target,
            staging,
            in_place,
        })
    }

    /// The folder to write the outputs into.
    pub fn dir(&self) -> &Path {
        &self.staging
    }

    /// Swaps the staged outputs in: every file of the old folder that no new output replaces
    /// is kept (the user's, and earlier outputs of physfit's other commands); an old file of
    /// the user's that a new output would replace makes it an error, the old folder untouched.
    pub fn commit(self) -> anyhow::Result<()> {
        // Dropping `self` then removes what is left at the staging path: the old folder after
        // an exchange, the staged outputs after a failure.
        self.swap()
    }

    fn swap(&self) -> anyhow::Result<()> {
        let new = files_under(&self.staging).context("listing the staged outputs")?;
        let tops: BTreeSet<String> = new
            .iter()
            .map(|f| f.split('/').next().unwrap_or(f).to_string())
            .collect();
        let mut manifest = new.clone();
        if self.target.is_dir() {
            let blocking = in_the_way(&self.target, &tops)?;
            if !blocking.is_empty() {
                return Err(refuse(&self.target, &blocking));
            }
            let owned = owned(&self.target);
            let old =
                files_under(&self.target).with_context(|| format!("reading {}", self.target.display()))?;
            for f in old {
                let top = f.split('/').next().unwrap_or(&f);
                if tops.contains(top) || f == MANIFEST {
                    continue;
                }
                if !self.in_place {
                    carry(&self.target.join(&f), &self.staging.join(&f))
                        .with_context(|| format!("keeping {}", self.target.join(&f).display()))?;
                }
                if owned.as_ref().is_some_and(|o| o.contains(&f)) {
                    manifest.insert(f);
                }
            }
        }
        let list: String = manifest.iter().map(|f| format!("{f}\n")).collect();
        physfit_model::write_atomic(&self.staging.join(MANIFEST), list.as_bytes())
            .context("writing the output list")?;
        let moved = if self.in_place {
            replace_entries(
                &self.staging,
                &self.target,
                tops.iter().map(String::as_str).chain([MANIFEST]),
            )
        } else {
            exchange(&self.staging, &self.target)
        };
        moved.with_context(|| format!("moving the outputs into {}", self.target.display()))
    }
}

impl Drop for Staged {
    /// An output folder abandoned (an error before [`Staged::commit`]) leaves nothing behind.
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.staging);
    }
}

/// Makes `to` the same file as `from` (a hard link; a copy where links are refused), creating
/// its folders; a symbolic link is recreated.
fn carry(from: &Path, to: &Path) -> std::io::Result<()> {
    if let Some(dir) = to.parent() {
        std::fs::create_dir_all(dir)?;
    }
    let meta = std::fs::symlink_metadata(from)?;
    if meta.file_type().is_symlink() {
        return std::os::unix::fs::symlink(std::fs::read_link(from)?, to);
    }
    std::fs::hard_link(from, to).or_else(|_| std::fs::copy(from, to).map(|_| ()))
}

/// Moves each of the top-level entries `names` of `staged` into `target`, replacing the entry of
/// that name (a folder is renamed into `staged` first, to be removed with it).
fn replace_entries<'a>(
    staged: &Path,
    target: &Path,
    names: impl Iterator<Item = &'a str>,
) -> std::io::Result<()> {
    for name in names {
        let dest = target.join(name);
        if dest.is_dir() {
            std::fs::rename(&dest, staged.join(format!(".old-{name}")))?;
        }
        std::fs::rename(staged.join(name), dest)?;
    }
    Ok(())
}

/// Puts the folder `staged` in the place of `target`, in one step where the system allows, and
/// removes the old folder.
fn exchange(staged: &Path, target: &Path) -> std::io::Result<()> {
    if !target.exists() {
        return std::fs::rename(staged, target);
    }
    if rename_exchange(staged, target).is_ok() {
        // `staged` now names the old folder, removed with the staging.
        return Ok(());
    }
    let (parent, name) = parent_and_name(target).map_err(std::io::Error::other)?;
    let aside = parent.join(format!(".{name}.physfit-old-{}", std::process::id()));
    std::fs::rename(target, &aside)?;
    if let Err(e) = std::fs::rename(staged, target) {
        let _ = std::fs::rename(&aside, target);
        return Err(e);
    }
    // Gone with the process if it is killed here: the next run removes it.
    std::fs::remove_dir_all(&aside)
}

/// Swaps the two paths atomically (Linux `renameat2` with `RENAME_EXCHANGE`).
#[cfg(target_os = "linux")]
fn rename_exchange(a: &Path, b: &Path) -> std::io::Result<()> {
    use std::ffi::CString;
    use std::os::unix::ffi::OsStrExt;
    let c = |p: &Path| CString::new(p.as_os_str().as_bytes()).map_err(std::io::Error::other);
    let (a, b) = (c(a)?, c(b)?);
    // SAFETY: both are valid NUL-terminated paths that outlive the call; the syscall reads them
    // only.
    let r = unsafe {
        libc::syscall(
            libc::SYS_renameat2,
            libc::AT_FDCWD,
            a.as_ptr(),
            libc::AT_FDCWD,
            b.as_ptr(),
            libc::RENAME_EXCHANGE,
        )
    };
    if r == 0 {
        Ok(())
    } else {
        Err(std::io::Error::last_os_error())
    }
}

/// Elsewhere there is no atomic exchange: the caller renames aside.
#[cfg(not(target_os = "linux"))]
fn rename_exchange(_: &Path, _: &Path) -> std::io::Result<()> {
    Err(std::io::Error::from(std::io::ErrorKind::Unsupported))
}
