//! Guards around a command's output folder: one writer at a time ([`OutputLock`]), nothing
//! half-written at the final path ([`Staged`]), no output inside the input
//! ([`refuse_output_inside`]), a folder walk that cannot loop through symlinks
//! ([`images_under`]), and single-file inputs that must be regular files ([`open_input`],
//! [`read_file`], [`read_text`]: a FIFO or a device would block or never end). docs/reliability.md lists
//! which command uses which.

use crate::error::{Error, Result};
use std::collections::HashSet;
use std::fs::{File, OpenOptions, TryLockError};
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Component, Path, PathBuf};

/// `out` made absolute and free of `.`/`..` and symlinks as far as it exists: the longest
/// existing ancestor is canonicalised and the rest appended. Two spellings of one folder
/// (relative, absolute, through a symlink) give the same result.
pub fn resolve(out: &Path) -> Result<PathBuf> {
    let abs = if out.is_absolute() {
        out.to_path_buf()
    } else {
        std::env::current_dir()
            .map_err(|e| Error::io(out, e))?
            .join(out)
    };
    let mut tail = Vec::new();
    let mut head = abs.as_path();
    loop {
        if let Ok(c) = head.canonicalize() {
            let mut r = c;
            for part in tail.iter().rev() {
                match part {
                    Component::ParentDir => {
                        r.pop();
                    }
                    Component::CurDir => {}
                    p => r.push(p),
                }
            }
            return Ok(r);
        }
        match (head.parent(), head.components().next_back()) {
            (Some(p), Some(last)) => {
                tail.push(last);
                head = p;
            }
            _ => return Ok(abs),
        }
    }
}

/// Error unless `output` lies outside `input` (neither equal to it nor below it), comparing
/// resolved paths, so `--out x`, `--out x/out`, `--out ./x/../x` and a symlink into `x` are all
/// refused for `--in x`.
pub fn refuse_output_inside(input: &Path, output: &Path) -> Result<()> {
    let (i, o) = (resolve(input)?, resolve(output)?);
    if o.starts_with(&i) {
        return Err(Error::layout(
            output,
            format!(
                "is {} the input {}: it would overwrite or re-read its own input; choose an \
                 output folder outside the input",
                if o == i {
                    "the same folder as"
                } else {
                    "inside"
                },
                input.display()
            ),
        ));
    }
    Ok(())
}

/// An exclusive lock on an output folder, held until dropped.
///
/// The lock is an OS advisory lock (`flock` on Unix, `LockFileEx` on Windows, through
/// `std::fs::File::try_lock`) on `OUT/.hdrsynth.lock`, which also records the holder's command
/// and pid for the message a second writer gets. Every command that writes an output folder
/// takes it on that folder, so any two of them exclude each other. The OS releases it when the
/// holder exits in any way, kill -9 included, so a dead holder never blocks a later run: there
/// are no stale locks to detect. The file stays in the folder (deleting it would let a waiter
/// lock an unlinked file); it means nothing when nobody holds it. A folder the lock created
/// and that holds nothing else when the lock is dropped (a command that failed before writing
/// anything, or a staged output that was never committed) is removed again. Network file
/// systems without `flock` support may not enforce the lock.
#[derive(Debug)]
pub struct OutputLock {
    file: Option<File>,
    lock_path: PathBuf,
    out: PathBuf,
    created: bool,
}

/// The lock file inside a locked output folder.
pub const LOCK_FILE: &str = ".hdrsynth.lock";

impl OutputLock {
    /// Create the folder `out` if needed and lock it for `command`, or fail naming the
    /// holder's command and pid.
    pub fn acquire(out: &Path, command: &str) -> Result<OutputLock> {
        let created = !out.exists();
        std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
        let resolved = resolve(out)?;
        let lock_path = resolved.join(LOCK_FILE);
        let mut file = OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&lock_path)
            .map_err(|e| Error::io(&lock_path, e))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(TryLockError::WouldBlock) => {
                let mut holder = String::new();
                let _ = file.read_to_string(&mut holder);
                return Err(Error::InUse {
                    path: out.to_path_buf(),
                    holder: match holder.trim() {
                        "" => "pid unknown".to_string(),
                        h => h.to_string(),
                    },
                    lock: lock_path,
                });
            }
            Err(TryLockError::Error(e)) => return Err(Error::io(&lock_path, e)),
        }
        let who = format!("{command}, pid {}", std::process::id());
        let res = (|| {
            file.set_len(0)?;
            file.seek(SeekFrom::Start(0))?;
            file.write_all(who.as_bytes())
        })();
        res.map_err(|e| Error::io(&lock_path, e))?;
        Ok(OutputLock {
            file: Some(file),
            lock_path,
            out: resolved,
            created,
        })
    }

    pub fn lock_path(&self) -> &Path {
        &self.lock_path
    }

    /// Stage this output in a temporary sibling (see [`Staged`]).
    pub fn stage(&self, resumable: bool) -> Result<Staged> {
        Staged::begin(&self.out, resumable)
    }
}

fn split(resolved: &Path, shown: &Path) -> Result<(PathBuf, String)> {
    match (resolved.parent(), resolved.file_name()) {
        (Some(p), Some(n)) => Ok((p.to_path_buf(), n.to_string_lossy().into_owned())),
        _ => Err(Error::layout(
            shown,
            "an output must be a named folder, not a file-system root",
        )),
    }
}

/// An output built in the hidden sibling `.<name>.partial` and moved into its final folder
/// only by [`Staged::commit`], so an error or a kill never leaves a half-written output where
/// readers look (the locked final folder holds only the lock file until then). Not resumable: the staging folder is removed on drop without commit, and a leftover
/// one (a kill) is cleared at the next start. Resumable: it is kept, and the next run continues
/// in it. Created through [`OutputLock::stage`], so one writer owns the staging name.
#[derive(Debug)]
pub struct Staged {
    tmp: PathBuf,
    out: PathBuf,
    resumable: bool,
    done: bool,
}

impl Staged {
    fn begin(out: &Path, resumable: bool) -> Result<Staged> {
        let (parent, name) = split(out, out)?;
        let tmp = parent.join(format!(".{name}.partial"));
        if !resumable && tmp.exists() {
            std::fs::remove_dir_all(&tmp).map_err(|e| Error::io(&tmp, e))?;
        }
        std::fs::create_dir_all(&tmp).map_err(|e| Error::io(&tmp, e))?;
        Ok(Staged {
            tmp,
            out: out.to_path_buf(),
            resumable,
            done: false,
        })
    }

    /// Where to write.
    pub fn path(&self) -> &Path {
        &self.tmp
    }

    /// Move the staged output into its final folder (which holds the lock), entry by entry:
    /// each an atomic rename, replacing files of the same name and merging folders, leaving
    /// other files in the final folder alone.
    pub fn commit(mut self) -> Result<PathBuf> {
        merge_into(&self.tmp, &self.out)?;
        std::fs::remove_dir_all(&self.tmp).map_err(|e| Error::io(&self.tmp, e))?;
        self.done = true;
        Ok(self.out.clone())
    }
}

impl Drop for OutputLock {
    fn drop(&mut self) {
        // Unlock (by closing) first; then remove a folder this lock created if nothing but
        // the lock file is in it.
        drop(self.file.take());
        if self.created
            && let Ok(mut entries) = std::fs::read_dir(&self.out)
            && entries.all(|e| e.is_ok_and(|e| e.file_name() == LOCK_FILE))
        {
            let _ = std::fs::remove_file(&self.lock_path);
            let _ = std::fs::remove_dir(&self.out);
        }
    }
}

impl Drop for Staged {
    fn drop(&mut self) {
        if !self.done && !self.resumable {
            let _ = std::fs::remove_dir_all(&self.tmp);
        }
    }
}

fn merge_into(src: &Path, dst: &Path) -> Result<()> {
    if !dst.is_dir() {
        return Err(Error::layout(
            dst,
            "exists and is not a folder; cannot write an output there",
        ));
    }
    for entry in std::fs::read_dir(src).map_err(|e| Error::io(src, e))? {
        let entry = entry.map_err(|e| Error::io(src, e))?;
        let (from, to) = (entry.path(), dst.join(entry.file_name()));
        let is_dir = entry.file_type().map_err(|e| Error::io(&from, e))?.is_dir();
        if is_dir && to.is_dir() {
            merge_into(&from, &to)?;
        } else {
            if is_dir && to.exists() {
                std::fs::remove_file(&to).map_err(|e| Error::io(&to, e))?;
            }
            std::fs::rename(&from, &to).map_err(|e| Error::io(&to, e))?;
        }
    }
    Ok(())
}

/// Every file under `dir` (sorted, recursive) that `keep` accepts. Symlinked folders are
/// followed once: a folder reached again (a symlink loop, or two links to one folder) is
/// skipped, so the walk always ends.
pub fn files_under(dir: &Path, keep: &dyn Fn(&Path) -> bool) -> Result<Vec<PathBuf>> {
    let mut seen = HashSet::new();
    let mut out = Vec::new();
    walk(dir, keep, &mut seen, &mut out)?;
    Ok(out)
}

fn walk(
    dir: &Path,
    keep: &dyn Fn(&Path) -> bool,
    seen: &mut HashSet<PathBuf>,
    out: &mut Vec<PathBuf>,
) -> Result<()> {
    let real = dir.canonicalize().map_err(|e| Error::io(dir, e))?;
    if !seen.insert(real) {
        return Ok(());
    }
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            walk(&p, keep, seen, out)?;
        } else if is_regular_file(&p) && keep(&p) {
            out.push(p);
        }
    }
    Ok(())
}

/// Whether `path` is (or links to) a regular file: the folder walk's filter (a FIFO, socket or
/// device in a folder is skipped).
pub fn is_regular_file(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| m.is_file())
}

/// The input file `path` opened for reading, or an error when it is not (a link to) a regular
/// file, saying what it is. The one way every single-file reader opens its input.
///
/// The test is made on the opened file (`fstat`), so nothing can swap the path between test and
/// open. On Unix the open itself cannot block: it is made with `O_NONBLOCK` (opening a FIFO for
/// reading otherwise waits for a writer, forever), which is cleared again on a regular file. A
/// missing file is the plain `NotFound` error, for the caller to word.
pub fn open_input(path: &Path) -> std::io::Result<File> {
    let mut opts = OpenOptions::new();
    opts.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        opts.custom_flags(libc::O_NONBLOCK);
    }
    let file = opts.open(path)?;
    let meta = file.metadata()?;
    if !meta.is_file() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            format!(
                "not a regular file but {}; give the path of a file",
                file_kind(&meta.file_type())
            ),
        ));
    }
    #[cfg(unix)]
    clear_nonblocking(&file)?;
    Ok(file)
}

/// Blocking reads again (regular files ignore the flag; cleared so that the handle behaves as
/// `File::open`'s whatever it is passed to).
#[cfg(unix)]
fn clear_nonblocking(file: &File) -> std::io::Result<()> {
    use std::os::fd::AsRawFd;
    let fd = file.as_raw_fd();
    // SAFETY: fcntl on a descriptor this `File` owns and keeps open; F_GETFL/F_SETFL touch
    // only its status flags.
    let flags = unsafe { libc::fcntl(fd, libc::F_GETFL) };
    if flags < 0 || unsafe { libc::fcntl(fd, libc::F_SETFL, flags & !libc::O_NONBLOCK) } < 0 {
        return Err(std::io::Error::last_os_error());
    }
    Ok(())
}

fn file_kind(t: &std::fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if t.is_socket() {
            return "a socket";
        }
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
    }
    if t.is_dir() { "a folder" } else { "not a file" }
}

/// The bytes of the input file `path` ([`open_input`]); the I/O error as it is, for callers
/// that word a missing file themselves.
pub fn read_input(path: &Path) -> std::io::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    open_input(path)?.read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// The text of the input file `path` ([`open_input`]); the I/O error as it is (`InvalidData`
/// when the file is not UTF-8).
pub fn read_input_text(path: &Path) -> std::io::Result<String> {
    let mut text = String::new();
    open_input(path)?.read_to_string(&mut text)?;
    Ok(text)
}

/// [`read_input`], errors naming the path.
pub fn read_file(path: &Path) -> Result<Vec<u8>> {
    read_input(path).map_err(|e| Error::io(path, e))
}

/// [`read_input_text`], errors naming the path.
pub fn read_text(path: &Path) -> Result<String> {
    read_input_text(path).map_err(|e| Error::io(path, e))
}

/// Whether a path has an image extension the readers know (exr, hdr, pic, png, tif, tiff).
pub fn is_image(p: &Path) -> bool {
    super::Format::from_path(p).is_ok()
}

/// Every image under `dir` ([`files_under`] with [`is_image`]).
pub fn images_under(dir: &Path) -> Result<Vec<PathBuf>> {
    files_under(dir, &is_image)
}
