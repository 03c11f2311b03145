//! Where an output goes, and what is left behind when a run stops: [`write_atomically`] (and
//! [`write_output`], [`write_bytes`] over it), the one writer of every file the commands make,
//! and [`Batch`] for a command's several outputs replaced together (all or none).
//!
//! - [`Target`]: a regular file (or a name not yet taken) is written through a temporary file
//!   renamed into place; anything else that exists (a FIFO, a character device such as
//!   `/dev/null`, a terminal, `/dev/stdout`) is written in place and never renamed over, as
//!   `cp`, `sed -i` and `sponge` do. A symbolic link is followed, so the link stays a link,
//!   also a dangling one (the file it names is created).
//! - Temporary files are named `.<name>.hvs-<pid>.<random>.tmp`. SIGINT, SIGTERM and SIGHUP
//!   remove the ones being written before the process dies of the signal (unless the command
//!   handles the signal itself, as `hvs track` does: it then finishes its files); after a
//!   SIGKILL the next write into the same directory removes the ones whose process is gone.
//! - A replaced file keeps its permissions; one this user may not write is refused.
//! - [`check_not_input`]: an output that is one of the inputs (same device and inode) is
//!   refused before any work; [`check_distinct`]: two outputs of one command on one file (the
//!   same name through links, `sub/../` or `./`, or the same inode) are refused too. Every
//!   command that writes checks both before it reads anything else.

use anyhow::{anyhow, bail, Context, Result};
use std::ffi::CString;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicI32, AtomicPtr, Ordering};
use std::sync::Mutex;

/// How an output path is written.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Target {
    /// Through a temporary file in the directory of this path (the link target for a
    /// symbolic link), renamed over it when complete.
    Atomic(PathBuf),
    /// Opened for writing and written in place (not a regular file: FIFO, device, ...).
    InPlace(PathBuf),
    /// The process' standard output (`/dev/stdout`, `/dev/fd/1`, `/proc/self/fd/1`).
    Stdout,
}

/// Classifies `path` (see the module documentation).
pub fn target(path: &Path) -> Result<Target> {
    let names_stdout = [
        "/dev/stdout",
        "/dev/fd/1",
        "/proc/self/fd/1",
        &format!("/proc/{}/fd/1", std::process::id()),
    ]
    .iter()
    .any(|s| Path::new(s) == path);
    if names_stdout {
        return Ok(Target::Stdout);
    }
    let link = std::fs::symlink_metadata(path).ok();
    if link.as_ref().is_some_and(|l| l.file_type().is_symlink()) && std::fs::metadata(path).is_err()
    {
        // A dangling link: create the file it names, keep the link.
        return Ok(Target::Atomic(link_target(path)?));
    }
    match std::fs::metadata(path) {
        Ok(m) if m.is_dir() => bail!("{}: is a directory", path.display()),
        Ok(m) if !m.is_file() => Ok(Target::InPlace(path.to_path_buf())),
        Ok(_) if link.is_some_and(|l| l.file_type().is_symlink()) => {
            // Replace the file the link points at, keep the link.
            Ok(Target::Atomic(std::fs::canonicalize(path)?))
        }
        _ => Ok(Target::Atomic(path.to_path_buf())),
    }
}

/// Where the (possibly dangling) symbolic link `path` points, followed to its end.
fn link_target(path: &Path) -> Result<PathBuf> {
    let mut at = path.to_path_buf();
    for _ in 0..40 {
        let next = std::fs::read_link(&at)
            .map_err(|e| anyhow::anyhow!("{}: cannot read the link: {e}", path.display()))?;
        let next = match at.parent() {
            Some(dir) if next.is_relative() => dir.join(next),
            _ => next,
        };
        match std::fs::symlink_metadata(&next) {
            Ok(m) if m.file_type().is_symlink() => at = next,
            _ => return Ok(next),
        }
    }
    bail!("{}: too many levels of symbolic links", path.display())
}

/// The file an output path names, for comparing outputs: the link target for a symbolic
/// link, the directory made canonical (`sub/../`, `./` and links in it resolved), `None` for
/// what is not written as a file (standard output, a device).
fn resolved(path: &Path) -> Option<PathBuf> {
    let p = match target(path).ok()? {
        Target::Atomic(p) => p,
        Target::InPlace(_) | Target::Stdout => return None,
    };
    let name = p.file_name()?;
    Some(std::fs::canonicalize(folder_of(&p)).ok()?.join(name))
}

/// Refuses two outputs of one command that name one file: `(flag, path)` each. Compared by
/// the name they resolve to ([`target`]'s link following, the directory made canonical) and,
/// for files that exist, by device and inode. Standard output and devices may be shared.
pub fn check_distinct(outputs: &[(&str, &Path)]) -> Result<()> {
    for (k, (fa, a)) in outputs.iter().enumerate() {
        for (fb, b) in &outputs[k + 1..] {
            let (Some(ra), Some(rb)) = (resolved(a), resolved(b)) else {
                continue;
            };
            let same_inode = match (std::fs::metadata(&ra), std::fs::metadata(&rb)) {
                (Ok(ma), Ok(mb)) => same_file(&ma, &mb),
                _ => false,
            };
            if ra == rb || same_inode {
                bail!(
                    "{fa} {} and {fb} {} are the same file (one would overwrite the other); give two different files",
                    a.display(),
                    b.display()
                );
            }
        }
    }
    Ok(())
}

/// [`check_distinct`] over the outputs, then [`check_not_input`] for each: what every
/// command that writes calls before any work.
pub fn check_outputs(outputs: &[(&str, &Path)], inputs: &[(&str, &Path)]) -> Result<()> {
    check_distinct(outputs)?;
    for (flag, out) in outputs {
        check_not_input(flag, out, inputs)?;
    }
    Ok(())
}

/// A warning for an output folder `dir` (`flag`) that already holds files: a run writes its
/// own files and list (`CAPTURES.csv`) but leaves the others as they were, so images of an
/// earlier, longer run would stay beside this one's. `None` for a missing or empty folder.
pub fn leftover_files_warning(flag: &str, dir: &Path) -> Option<String> {
    let n = std::fs::read_dir(dir).ok()?.filter_map(|e| e.ok()).count();
    (n > 0).then(|| {
        format!(
            "{flag} {}: the folder already holds {n} file(s); this run's files replace those of the same names, the others stay (its CAPTURES.csv lists only this run's)",
            dir.display()
        )
    })
}

/// Refuses a folder output (`flag`, e.g. `--overlays`) that cannot be a folder to write in:
/// an existing file or device, a read-only folder, or a new folder whose parent does not
/// exist or is read-only. Checked before any work; the folder is created when written.
pub fn check_dir_output(flag: &str, dir: &Path) -> Result<()> {
    let shown = dir.display();
    match std::fs::metadata(dir) {
        Ok(m) if !m.is_dir() => bail!("{flag} {shown}: exists and is not a directory"),
        Ok(_) => {
            if !writable(dir) {
                bail!("{flag} {shown}: the folder is not writable");
            }
        }
        Err(_) => {
            let parent = folder_of(dir);
            if !parent.is_dir() {
                bail!(
                    "{flag} {shown}: cannot create the folder: {} does not exist",
                    parent.display()
                );
            }
            if !writable(parent) {
                bail!(
                    "{flag} {shown}: cannot create the folder: {} is not writable",
                    parent.display()
                );
            }
        }
    }
    Ok(())
}

/// Whether this process may write into the directory `dir` (`access(2)`).
#[cfg(unix)]
fn writable(dir: &Path) -> bool {
    may(dir, libc::W_OK | libc::X_OK)
}

/// Whether this process may write the existing file `path` (`access(2)`, as the shell's
/// `test -w`; root may).
#[cfg(unix)]
fn file_writable(path: &Path) -> bool {
    may(path, libc::W_OK)
}

#[cfg(unix)]
fn may(path: &Path, mode: libc::c_int) -> bool {
    use std::os::unix::ffi::OsStrExt;
    let Ok(c) = std::ffi::CString::new(path.as_os_str().as_bytes()) else {
        return false;
    };
    // SAFETY: access only reads the NUL-terminated path.
    unsafe { libc::access(c.as_ptr(), mode) == 0 }
}

#[cfg(not(unix))]
fn writable(_: &Path) -> bool {
    true
}

#[cfg(not(unix))]
fn file_writable(_: &Path) -> bool {
    true
}

/// Creates the output folder `dir` (given as `flag`) if missing; whether it did (for
/// [`remove_if_created`]).
pub fn create_folder(flag: &str, dir: &Path) -> Result<bool> {
    let created = !dir.exists();
    std::fs::create_dir_all(dir)
        .map_err(|e| anyhow!("{flag} {}: cannot create the folder: {e}", dir.display()))?;
    Ok(created)
}

/// Removes the output folder `dir` when this run `created` it ([`create_folder`]) and it is
/// empty (nothing was written, or a [`Batch`] was dropped): nothing is left behind. A folder
/// that holds anything stays.
pub fn remove_if_created(dir: &Path, created: bool) {
    if created {
        // Fails (and is left alone) unless empty.
        let _ = std::fs::remove_dir(dir);
    }
}

/// Fails unless the directory `path` would be written in exists, so that a command can
/// refuse a bad `-o` before any work (the same message as the writer's).
pub fn check_dir(path: &Path) -> Result<()> {
    let dir = folder_of(path);
    if !dir.is_dir() {
        bail!("{}: the directory {} does not exist", path.display(), dir.display());
    }
    Ok(())
}

/// Refuses an output that is also an input: `output` (the flag's value, named `out_flag` in
/// the message, e.g. `-o`) against each `(flag, path)` input. Files are compared by device
/// and inode (so hard links and symbolic links are caught), only when the output is an
/// existing regular file (`-o /dev/stdout` next to `--points /dev/stdin` is fine). Also
/// fails when the output's directory does not exist ([`check_dir`]).
pub fn check_not_input(out_flag: &str, output: &Path, inputs: &[(&str, &Path)]) -> Result<()> {
    match target(output)? {
        Target::Atomic(p) => check_dir(&p)?,
        Target::InPlace(_) | Target::Stdout => return Ok(()),
    }
    let Ok(om) = std::fs::metadata(output) else {
        return Ok(());
    };
    if !om.is_file() {
        return Ok(());
    }
    for (flag, input) in inputs {
        let Ok(im) = std::fs::metadata(input) else {
            continue;
        };
        if same_file(&om, &im) {
            bail!(
                "{out_flag} {} is also the {flag} input (it would be overwritten); write to another file",
                output.display()
            );
        }
    }
    Ok(())
}

/// The folder `path` is in: its parent, or `.` for a bare file name.
fn folder_of(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Whether `path` names a file in the folder `dir` whose name `written` says a command writes
/// there (`hvs track --record`'s frames, `hvs collect`'s images): a command that writes a
/// family of names, known by their pattern before the run, checks its inputs with it before
/// any work. The folders are compared made canonical; a folder not made yet holds nothing,
/// and a name under it is the command's own.
pub fn names_file_in(dir: &Path, path: &Path, written: impl Fn(&str) -> bool) -> bool {
    let Some(name) = path.file_name().and_then(|n| n.to_str()) else { return false };
    if !written(name) {
        return false;
    }
    let parent = folder_of(path);
    match (std::fs::canonicalize(parent), std::fs::canonicalize(dir)) {
        (Ok(p), Ok(d)) => p == d,
        _ => parent.components().eq(dir.components()),
    }
}

/// Whether two files' metadata are of one file (the same device and inode).
#[cfg(unix)]
pub(crate) fn same_file(a: &std::fs::Metadata, b: &std::fs::Metadata) -> bool {
    use std::os::unix::fs::MetadataExt;
    a.dev() == b.dev() && a.ino() == b.ino()
}

#[cfg(not(unix))]
pub(crate) fn same_file(_: &std::fs::Metadata, _: &std::fs::Metadata) -> bool {
    false
}

/// The marker between the output's name and the pid in a temporary file's name.
const MARK: &str = ".hvs-";

/// The prefix of this process' temporary files for `file_name`: `.<name>.hvs-<pid>.`.
pub fn temp_prefix(file_name: &str) -> String {
    format!(".{file_name}{MARK}{}.", std::process::id())
}

/// The pid in a temporary file's name written by [`temp_prefix`] (plus random part and
/// `.tmp`), if `name` is one.
pub fn temp_owner(name: &str) -> Option<u32> {
    let rest = name.strip_prefix('.')?.strip_suffix(".tmp")?;
    let at = rest.rfind(MARK)?;
    let (pid, random) = rest[at + MARK.len()..].split_once('.')?;
    if pid.is_empty() || !pid.bytes().all(|b| b.is_ascii_digit()) || random.is_empty() {
        return None;
    }
    pid.parse().ok()
}

/// Removes the temporary files in `dir` left by `hvs` processes that no longer run (killed
/// with SIGKILL, or by a power cut) and owned by this user. Errors are ignored: this is
/// housekeeping, never a reason to fail a write.
pub fn remove_stale(dir: &Path) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    let me = std::process::id();
    for e in entries.flatten() {
        let name = e.file_name();
        let Some(pid) = name.to_str().and_then(temp_owner) else {
            continue;
        };
        if pid == me || process_alive(pid) {
            continue;
        }
        let Ok(m) = std::fs::symlink_metadata(e.path()) else {
            continue;
        };
        if m.is_file() && owned_by_me(&m) {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

#[cfg(unix)]
fn process_alive(pid: u32) -> bool {
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return false;
    };
    if pid <= 0 {
        return true;
    }
    // SAFETY: kill with signal 0 only checks whether the process exists.
    let r = unsafe { libc::kill(pid, 0) };
    r == 0 || std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH)
}

#[cfg(not(unix))]
fn process_alive(_: u32) -> bool {
    true
}

#[cfg(unix)]
fn owned_by_me(m: &std::fs::Metadata) -> bool {
    use std::os::unix::fs::MetadataExt;
    // SAFETY: geteuid has no preconditions.
    m.uid() == unsafe { libc::geteuid() }
}

#[cfg(not(unix))]
fn owned_by_me(_: &std::fs::Metadata) -> bool {
    false
}

/// Temporary files being written, for the signal handler: each slot holds a `CString`
/// pointer, null (free) or [`tomb`] (visited by the handler: never taken again). Whoever swaps
/// a pointer out owns it (the handler only unlinks and dies).
const SLOTS: usize = 8192;
#[allow(clippy::declare_interior_mutable_const)]
const EMPTY: AtomicPtr<libc::c_char> = AtomicPtr::new(std::ptr::null_mut());
static PENDING: [AtomicPtr<libc::c_char>; SLOTS] = [EMPTY; SLOTS];
/// Set by the signal handler before it removes the temporary files: no new one is made.
static DYING: AtomicBool = AtomicBool::new(false);
static TOMB: u8 = 0;

/// The marker of a slot the handler has visited. A thread that registers a file while the
/// handler sweeps the slots can then only take a slot the sweep has still to reach (one the
/// sweep had emptied could be taken behind it, and the file was left: two of a parallel
/// `hvs collect`'s images in one Ctrl-C in two).
fn tomb() -> *mut libc::c_char {
    std::ptr::addr_of!(TOMB).cast_mut().cast()
}

/// Waits for the signal that set [`DYING`] to end the process.
fn wait_for_death() -> ! {
    loop {
        std::thread::park();
    }
}

/// A temporary file registered for removal on SIGINT/SIGTERM/SIGHUP; unregisters on drop.
#[derive(Debug)]
pub struct Pending {
    slot: Option<(usize, *mut libc::c_char)>,
}

// SAFETY: the pointer is a `CString` this value owns alone (taken back only by whoever swaps
// it out of its slot); nothing reads through it but `unlink` and the drop, from any thread.
unsafe impl Send for Pending {}

impl Pending {
    /// Registers `path` (installs the signal handlers on first use).
    pub fn register(path: &Path) -> Pending {
        install_handlers();
        let Ok(c) = CString::new(path.as_os_str().as_encoded_bytes()) else {
            return Pending { slot: None };
        };
        let p = c.into_raw();
        for (i, s) in PENDING.iter().enumerate() {
            if s.compare_exchange(std::ptr::null_mut(), p, Ordering::SeqCst, Ordering::SeqCst)
                .is_ok()
            {
                if DYING.load(Ordering::SeqCst) {
                    // The handler is removing the files: make no more.
                    wait_for_death();
                }
                return Pending { slot: Some((i, p)) };
            }
        }
        if DYING.load(Ordering::SeqCst) {
            wait_for_death();
        }
        // All slots taken: the file is still removed by the next write after the process
        // is gone (remove_stale).
        // SAFETY: p came from CString::into_raw above and was not shared.
        drop(unsafe { CString::from_raw(p) });
        Pending { slot: None }
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        if let Some((i, p)) = self.slot.take() {
            if PENDING[i]
                .compare_exchange(p, std::ptr::null_mut(), Ordering::SeqCst, Ordering::SeqCst)
                .is_ok()
            {
                // SAFETY: p came from CString::into_raw and we took it back out of the slot.
                drop(unsafe { CString::from_raw(p) });
            }
        }
    }
}

#[cfg(unix)]
extern "C" fn on_signal(sig: libc::c_int) {
    if HOLDING.load(Ordering::SeqCst) {
        // A batch is being renamed into place: finish it first (HeldSignals' drop).
        DEFERRED.store(sig, Ordering::SeqCst);
        return;
    }
    DYING.store(true, Ordering::SeqCst);
    for s in &PENDING {
        let p = s.swap(tomb(), Ordering::SeqCst);
        if !p.is_null() && p != tomb() {
            // SAFETY: p is a NUL-terminated path; unlink is async-signal-safe.
            unsafe { libc::unlink(p) };
        }
    }
    // Die of the signal as if there were no handler (the shell sees 128 + sig).
    // SAFETY: signal and raise are async-signal-safe.
    unsafe {
        libc::signal(sig, libc::SIG_DFL);
        libc::raise(sig);
    }
}

#[cfg(unix)]
fn install_handlers() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        for sig in [libc::SIGINT, libc::SIGTERM, libc::SIGHUP] {
            // SAFETY: plain sigaction calls; a signal ignored at start (nohup, background
            // jobs) stays ignored, and one the command handles itself (`hvs track`'s loop
            // ends on it and then writes its log and record) stays its own: the files then
            // land whole.
            unsafe {
                let mut old: libc::sigaction = std::mem::zeroed();
                if libc::sigaction(sig, std::ptr::null(), &mut old) != 0
                    || old.sa_sigaction != libc::SIG_DFL
                {
                    continue;
                }
                let mut act: libc::sigaction = std::mem::zeroed();
                act.sa_sigaction = on_signal as extern "C" fn(libc::c_int) as usize;
                libc::sigemptyset(&mut act.sa_mask);
                libc::sigaction(sig, &act, std::ptr::null_mut());
            }
        }
    });
}

#[cfg(not(unix))]
fn install_handlers() {}

/// Writes to `path` atomically: everything goes to a temporary file in the same directory,
/// which replaces `path` only after `body` succeeded and the data reached the disk. On any
/// error the temporary file is removed and `path` is untouched.
///
/// Only regular files (and names not yet taken) are replaced so; an existing FIFO or device
/// (`/dev/null`, a terminal) is written in place, `/dev/stdout` is standard output, and a
/// symbolic link stays a link to the file it names ([`target`]).
pub fn write_atomically<F>(path: &Path, body: F) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> Result<()>,
{
    let path = match target(path)? {
        Target::Stdout => return write_output(None, body),
        Target::InPlace(p) => return write_in_place(&p, body),
        Target::Atomic(p) => p,
    };
    stage(&path, body, &mut |_| true)?.persist()
}

/// A complete temporary file, synced, waiting to be renamed over its output.
struct Staged {
    tmp: tempfile::TempPath,
    path: PathBuf,
    _pending: Option<Pending>,
}

impl Staged {
    fn persist(self) -> Result<()> {
        let Staged { tmp, path, _pending } = self;
        tmp.persist(&path).map_err(|e| anyhow!("{}: cannot write: {}", path.display(), e.error))
    }
}

/// Writes `body` into a temporary file beside `path` (a [`Target::Atomic`] path), synced to
/// the disk and registered for removal on a signal; dropped, the file is removed.
///
/// `clean(dir)` says whether to remove what killed runs left in the directory first
/// ([`remove_stale`]): once per directory is enough for a batch of many files.
fn stage<F>(path: &Path, body: F, clean: &mut dyn FnMut(&Path) -> bool) -> Result<Staged>
where
    F: FnOnce(&mut dyn Write) -> Result<()>,
{
    let dir = folder_of(path).to_path_buf();
    let fname = path.file_name().ok_or_else(|| anyhow!("{}: not a file name", path.display()))?;
    let prefix = temp_prefix(&fname.to_string_lossy());
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".tmp");
    if !dir.exists() {
        bail!("{}: the directory {} does not exist", path.display(), dir.display());
    }
    if !dir.is_dir() {
        bail!("{}: {} is not a directory", path.display(), dir.display());
    }
    // A file replaced keeps its permissions, and one this user may not write is not replaced
    // (as the shell's `>` refuses it), though the directory would allow the rename.
    let existing = std::fs::metadata(path).ok().filter(std::fs::Metadata::is_file);
    if existing.is_some() && !file_writable(path) {
        bail!(
            "{}: cannot replace it: {} (a file this user may not write)",
            path.display(),
            std::io::Error::last_os_error()
        );
    }
    if clean(&dir) {
        remove_stale(&dir);
    }
    // Registered for removal by SIGINT/SIGTERM/SIGHUP *before* it is created (a signal
    // between creating and registering would leave it behind); unregistered after the
    // rename. Created like any new file (0666 less the umask), not tempfile's private 0600.
    let mut pending = None;
    let tmp = builder
        .make_in(&dir, |p| {
            pending = Some(Pending::register(p));
            let mut o = std::fs::OpenOptions::new();
            o.write(true).create_new(true);
            #[cfg(unix)]
            std::os::unix::fs::OpenOptionsExt::mode(&mut o, 0o666);
            let f = o.open(p);
            if DYING.load(Ordering::SeqCst) {
                // The handler began after the registration: it may have swept this slot
                // before the file existed. Remove it here (removing it twice is harmless).
                let _ = std::fs::remove_file(p);
                wait_for_death();
            }
            f
        })
        // The error names the output and its directory, not the temporary file's random
        // name (tempfile's message would).
        .map_err(|e| {
            anyhow!(
                "{}: cannot create a file in {}: {}",
                path.display(),
                dir.display(),
                std::io::Error::from(e.kind())
            )
        })?;
    if let Some(m) = &existing {
        tmp.as_file()
            .set_permissions(m.permissions())
            .with_context(|| format!("{}: cannot keep its permissions", path.display()))?;
    }
    let mut w = BufWriter::new(tmp);
    body(&mut w)?;
    let tmp =
        w.into_inner().map_err(|e| anyhow!("{}: cannot write: {}", path.display(), e.error()))?;
    tmp.as_file().sync_all().with_context(|| format!("{}: cannot write", path.display()))?;
    Ok(Staged { tmp: tmp.into_temp_path(), path: path.to_path_buf(), _pending: pending })
}

/// The outputs of one command, replaced all together or not at all: each file is written to
/// its temporary file as it is added ([`Batch::add`]), and [`Batch::commit`] renames them all
/// over their outputs, with SIGINT, SIGTERM and SIGHUP held back until the last rename (the
/// process then dies of the signal). A batch dropped uncommitted (an error, a panic) or a
/// signal before the commit leaves every output as it was: a rerun stopped half-way never
/// mixes new files with the last run's (a capture set's images with the last `board.json`).
/// Outputs that are not regular files (a device, standard output) are kept in memory and
/// written at the commit, before the renames.
/// Files may be added from several threads at once.
#[derive(Default)]
pub struct Batch {
    staged: Mutex<Vec<Staged>>,
    direct: Mutex<Vec<(Option<PathBuf>, Vec<u8>)>>,
    /// The directories [`remove_stale`] has cleaned for this batch.
    cleaned: Mutex<Vec<PathBuf>>,
}

impl Batch {
    /// An empty batch.
    pub fn new() -> Batch {
        Batch::default()
    }

    /// Writes `bytes` for `path` (to its temporary file; see [`Batch`]).
    pub fn add(&self, path: &Path, bytes: &[u8]) -> Result<()> {
        match target(path)? {
            Target::Atomic(p) => {
                let mut first_time = |dir: &Path| {
                    let mut cleaned = lock(&self.cleaned);
                    let new = !cleaned.iter().any(|d| d == dir);
                    if new {
                        cleaned.push(dir.to_path_buf());
                    }
                    new
                };
                let st = stage(
                    &p,
                    |w| {
                        w.write_all(bytes).with_context(|| format!("{}: cannot write", p.display()))
                    },
                    &mut first_time,
                )?;
                lock(&self.staged).push(st);
            }
            Target::InPlace(p) => lock(&self.direct).push((Some(p), bytes.to_vec())),
            Target::Stdout => lock(&self.direct).push((None, bytes.to_vec())),
        }
        Ok(())
    }

    /// Writes the outputs that are not regular files, then renames every temporary file
    /// over its output (see [`Batch`]).
    pub fn commit(self) -> Result<()> {
        let (staged, direct) = (into_inner(self.staged), into_inner(self.direct));
        for (path, bytes) in &direct {
            match path {
                Some(p) => write_in_place(p, |w| Ok(w.write_all(bytes)?))?,
                None => write_output(None, |w| Ok(w.write_all(bytes)?))?,
            }
        }
        let _held = HeldSignals::hold();
        let _dirs = lock_dirs(&staged);
        for st in staged {
            st.persist()?;
        }
        Ok(())
    }
}

/// Exclusive `flock`s of the directories `staged` renames into, taken in one order (their
/// canonical paths, sorted) and held until dropped: two commands committing batches into the
/// same folder at once rename their files one batch after the other, so the folder never holds
/// one run's depth map beside the other's matches (a QA pass, 2026-12-08: 2 of 20 pairs of
/// `hvs depth` runs started together mixed them). Best effort: a directory that cannot be
/// opened or locked (a file system without `flock`) is committed unlocked, as before.
fn lock_dirs(staged: &[Staged]) -> Vec<std::fs::File> {
    let mut dirs: Vec<PathBuf> =
        staged.iter().filter_map(|st| std::fs::canonicalize(folder_of(&st.path)).ok()).collect();
    dirs.sort();
    dirs.dedup();
    dirs.iter()
        .filter_map(|d| {
            use std::os::fd::AsRawFd;
            let f = std::fs::File::open(d).ok()?;
            // SAFETY: `flock` on a descriptor `f` owns; the lock goes with it when `f` closes.
            (unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_EX) } == 0).then_some(f)
        })
        .collect()
}

/// The guarded value, also after a panic on another thread while it held the lock (a file
/// list stays a valid list).
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

fn into_inner<T>(m: Mutex<T>) -> T {
    m.into_inner().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// The signal that arrived while [`HeldSignals`] held them back (0: none).
static DEFERRED: AtomicI32 = AtomicI32::new(0);
/// Whether signals are held back ([`HeldSignals`]).
static HOLDING: AtomicBool = AtomicBool::new(false);

/// While alive, SIGINT, SIGTERM and SIGHUP are noted instead of handled; dropped, a noted
/// signal is handled (the pending temporary files removed, the process dies of it).
struct HeldSignals;

impl HeldSignals {
    fn hold() -> HeldSignals {
        install_handlers();
        HOLDING.store(true, Ordering::SeqCst);
        HeldSignals
    }
}

impl Drop for HeldSignals {
    fn drop(&mut self) {
        HOLDING.store(false, Ordering::SeqCst);
        let sig = DEFERRED.swap(0, Ordering::SeqCst);
        #[cfg(unix)]
        if sig != 0 {
            on_signal(sig);
        }
        #[cfg(not(unix))]
        let _ = sig;
    }
}

/// Writes into an existing file that is not a regular file (FIFO, device), without
/// replacing it.
fn write_in_place<F>(path: &Path, body: F) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> Result<()>,
{
    let f = std::fs::OpenOptions::new()
        .write(true)
        .open(path)
        .with_context(|| format!("{}: cannot open for writing", path.display()))?;
    let mut w = BufWriter::new(f);
    // The body may already name the file (write_bytes does): name it once.
    let shown = path.display().to_string();
    body(&mut w).map_err(|e| {
        if e.to_string().starts_with(&shown) {
            e
        } else {
            e.context(format!("{shown}: cannot write"))
        }
    })?;
    w.flush().with_context(|| format!("{}: cannot write", path.display()))?;
    Ok(())
}

/// Writes to `path` atomically ([`write_atomically`]), or to stdout when `path` is `None`.
pub fn write_output<F>(path: Option<&Path>, body: F) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> Result<()>,
{
    match path {
        Some(p) => write_atomically(p, body),
        None => {
            let stdout = std::io::stdout();
            let mut w = BufWriter::new(stdout.lock());
            body(&mut w).context("cannot write to stdout")?;
            w.flush().context("cannot write to stdout")?;
            Ok(())
        }
    }
}

/// Writes bytes to `path` atomically.
pub fn write_bytes(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomically(path, |w| {
        w.write_all(bytes).with_context(|| format!("{}: cannot write", path.display()))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_with_files_is_warned_about() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("new");
        assert_eq!(leftover_files_warning("-o", &missing), None);
        std::fs::create_dir(&missing).unwrap();
        assert_eq!(leftover_files_warning("-o", &missing), None);
        std::fs::write(missing.join("left0001.png"), b"x").unwrap();
        let w = leftover_files_warning("--record", &missing).unwrap();
        assert!(w.starts_with("--record ") && w.contains("holds 1 file(s)"), "{w}");
    }

    #[test]
    fn temp_names_carry_the_pid() {
        let p = temp_prefix("int.csv");
        let me = std::process::id();
        assert_eq!(temp_owner(&format!("{p}a1B2c3.tmp")), Some(me));
        assert_eq!(temp_owner(".x.hvs-12.abc.tmp"), Some(12));
        assert_eq!(temp_owner(".a.hvs-b.csv.hvs-7.zz.tmp"), Some(7));
        for other in [
            ".int.csv.abc.tmp",
            "x.hvs-12.abc.tmp",
            ".x.hvs-12.abc",
            ".x.hvs-.abc.tmp",
            ".x.hvs-1a.abc.tmp",
            ".x.hvs-12..tmp",
        ] {
            assert_eq!(temp_owner(other), None, "{other}");
        }
    }

    #[test]
    fn targets_by_kind() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("f.csv");
        assert_eq!(target(&f).unwrap(), Target::Atomic(f.clone()));
        std::fs::write(&f, "x").unwrap();
        assert_eq!(target(&f).unwrap(), Target::Atomic(f.clone()));
        assert_eq!(target(Path::new("/dev/null")).unwrap(), Target::InPlace("/dev/null".into()));
        assert_eq!(target(Path::new("/dev/stdout")).unwrap(), Target::Stdout);
        assert!(target(dir.path()).is_err());
        #[cfg(unix)]
        {
            let l = dir.path().join("l.csv");
            std::os::unix::fs::symlink(&f, &l).unwrap();
            let real = std::fs::canonicalize(&f).unwrap();
            assert_eq!(target(&l).unwrap(), Target::Atomic(real));
        }
    }

    #[cfg(unix)]
    #[test]
    fn a_dangling_link_stays_a_link_and_outputs_are_distinct() {
        let dir = tempfile::tempdir().unwrap();
        let l = dir.path().join("l.csv");
        std::os::unix::fs::symlink("real.csv", &l).unwrap();
        assert_eq!(target(&l).unwrap(), Target::Atomic(dir.path().join("real.csv")));
        let sub = dir.path().join("sub");
        std::fs::create_dir(&sub).unwrap();
        let a = dir.path().join("a.csv");
        let via = sub.join("..").join("a.csv");
        let e = check_distinct(&[("-o", &a), ("--overlay", &via)]).unwrap_err().to_string();
        assert!(e.contains("are the same file"), "{e}");
        // Through a (dangling) link to the same name, not yet written.
        let e = check_distinct(&[("-o", &l), ("--x", &dir.path().join("real.csv"))])
            .unwrap_err()
            .to_string();
        assert!(e.contains("are the same file"), "{e}");
        check_distinct(&[("-o", &a), ("--overlay", &dir.path().join("b.csv"))]).unwrap();
        check_distinct(&[("-o", Path::new("/dev/null")), ("--x", Path::new("/dev/null"))]).unwrap();
        // An input reached through sub/../ is refused as an output.
        std::fs::write(&a, "x").unwrap();
        let e = check_outputs(&[("-o", &via)], &[("--captures", &a)]).unwrap_err().to_string();
        assert!(e.contains("is also the --captures input"), "{e}");
    }

    #[test]
    fn an_input_is_not_an_output() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.csv");
        let b = dir.path().join("b.csv");
        std::fs::write(&a, "x").unwrap();
        std::fs::write(&b, "x").unwrap();
        let dotted = dir.path().join(".").join("a.csv");
        let e = check_not_input("-o", &dotted, &[("--model", &b), ("--points", &a)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("is also the --points input"), "{e}");
        check_not_input("-o", &b, &[("--points", &a)]).unwrap();
        check_not_input("-o", &dir.path().join("new.csv"), &[("--points", &a)]).unwrap();
        check_not_input("-o", Path::new("/dev/null"), &[("--points", Path::new("/dev/null"))])
            .unwrap();
    }

    /// The files of `dir`, sorted, temporary files included.
    fn listing(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_batch_replaces_all_its_outputs_or_none() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.pfm"), dir.path().join("b.png"));
        std::fs::write(&a, "old a").unwrap();
        std::fs::write(&b, "old b").unwrap();
        // A later output that cannot be written: the earlier one is not replaced either.
        let batch = Batch::new();
        batch.add(&a, b"new a").unwrap();
        let e = batch.add(&dir.path().join("missing/c.ply"), b"c").unwrap_err().to_string();
        assert!(e.contains("does not exist"), "{e}");
        drop(batch);
        assert_eq!(std::fs::read(&a).unwrap(), b"old a");
        assert_eq!(listing(dir.path()), ["a.pfm", "b.png"]);
        // A directory where one is expected is named as not one.
        let e = Batch::new().add(&a.join("x.pfm"), b"x").unwrap_err().to_string();
        assert!(e.contains("is not a directory"), "{e}");
        // Staged but not committed: nothing is replaced until the commit.
        let batch = Batch::new();
        batch.add(&a, b"new a").unwrap();
        batch.add(&b, b"new b").unwrap();
        assert_eq!(std::fs::read(&b).unwrap(), b"old b");
        batch.commit().unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"new a");
        assert_eq!(std::fs::read(&b).unwrap(), b"new b");
        assert_eq!(listing(dir.path()), ["a.pfm", "b.png"]);
    }

    /// A commit waits for another's lock on the folder it renames into, so two runs writing the
    /// same outputs at once replace them one whole batch after the other.
    #[test]
    fn a_commit_waits_for_the_folders_lock() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("d.pfm"), dir.path().join("m.pfm"));
        let batch = Batch::new();
        batch.add(&a, b"new a").unwrap();
        batch.add(&b, b"new b").unwrap();
        let held = std::fs::File::open(dir.path()).unwrap();
        // SAFETY: as in `lock_dirs`.
        let r = unsafe { libc::flock(std::os::fd::AsRawFd::as_raw_fd(&held), libc::LOCK_EX) };
        assert_eq!(r, 0);
        let t = std::thread::spawn(move || batch.commit());
        std::thread::sleep(std::time::Duration::from_millis(200));
        assert!(!a.exists() && !b.exists(), "committed under another's lock");
        drop(held);
        t.join().unwrap().unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), b"new a");
        assert_eq!(std::fs::read(&b).unwrap(), b"new b");
    }

    #[cfg(unix)]
    #[test]
    fn a_replaced_file_keeps_its_permissions() {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("private.csv");
        for mode in [0o600, 0o640, 0o755] {
            std::fs::write(&p, "old").unwrap();
            std::fs::set_permissions(&p, std::fs::Permissions::from_mode(mode)).unwrap();
            write_bytes(&p, b"new").unwrap();
            assert_eq!(std::fs::read(&p).unwrap(), b"new");
            let got = std::fs::metadata(&p).unwrap().permissions().mode() & 0o777;
            assert_eq!(got, mode, "{got:o} for {mode:o}");
        }
        // A read-only file: refused unless this user may write it anyway (root may).
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o444)).unwrap();
        let r = write_bytes(&p, b"newer");
        if file_writable(&p) {
            r.unwrap();
            assert_eq!(std::fs::metadata(&p).unwrap().permissions().mode() & 0o777, 0o444);
        } else {
            let e = r.unwrap_err().to_string();
            assert!(e.contains("cannot replace it"), "{e}");
            assert_eq!(std::fs::read(&p).unwrap(), b"new");
        }
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn a_batch_whose_device_output_fails_replaces_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let a = dir.path().join("a.pfm");
        std::fs::write(&a, "old a").unwrap();
        let batch = Batch::new();
        batch.add(&a, b"new a").unwrap();
        batch.add(Path::new("/dev/full"), b"colour").unwrap();
        let e = format!("{:#}", batch.commit().unwrap_err());
        assert!(e.contains("/dev/full"), "{e}");
        assert_eq!(std::fs::read(&a).unwrap(), b"old a");
        assert_eq!(listing(dir.path()), ["a.pfm"]);
    }
}
