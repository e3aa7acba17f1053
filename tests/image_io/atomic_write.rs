//! Atomic writes: a missing folder, a folder in the way, failures that leave the old
//! content, symbolic links and devices, several files all or nothing.

use std::path::Path;

use texsyn::image_io::{save_image_atomic, write_atomic};
use texsyn::Error;

use crate::common::TempDir;

#[test]
fn atomic_write_to_missing_directory() {
    let dir = TempDir::new("atomic-missing");
    let path = dir.join("no/such/dir/out.png");
    let r = write_atomic(&path, |w| {
        use std::io::Write;
        w.write_all(b"data").unwrap();
        Ok(())
    });
    match r {
        Err(Error::Write { path: p, reason }) => {
            assert_eq!(p, path);
            assert!(reason.contains("does not exist"), "{reason}");
        }
        other => panic!("expected Write, got {other:?}"),
    }
    assert!(!path.exists());
    assert!(dir.entries().is_empty());
}

#[test]
fn atomic_write_to_a_directory() {
    let dir = TempDir::new("atomic-dir");
    let target = dir.join("adir");
    std::fs::create_dir(&target).unwrap();
    let r = write_atomic(&target, |_| Ok(()));
    assert!(matches!(r, Err(Error::Write { .. })), "{r:?}");
    assert!(target.is_dir());
    assert_eq!(dir.entries(), vec!["adir".to_string()]);
    // Also through the image saver.
    let r = save_image_atomic(&dir.join("adir"), 1, 1, 4, &[0; 4]);
    assert!(matches!(r, Err(Error::Write { .. })), "{r:?}");
}

#[test]
fn failed_write_leaves_no_temp_and_keeps_old_content() {
    use std::io::Write;
    let dir = TempDir::new("atomic-fail");
    let path = dir.join("out.bin");
    std::fs::write(&path, b"old content").unwrap();

    // The writer fails half way.
    let r = write_atomic(&path, |w| {
        w.write_all(&[1; 100_000]).unwrap();
        Err(Error::InvalidParameter("simulated failure".into()))
    });
    match r {
        Err(Error::Write { path: p, reason }) => {
            assert_eq!(p, path);
            assert!(reason.contains("simulated failure"), "{reason}");
        }
        other => panic!("expected Write, got {other:?}"),
    }
    assert_eq!(std::fs::read(&path).unwrap(), b"old content");
    assert_eq!(dir.entries(), vec!["out.bin".to_string()]);

    // The writer panics.
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let _ = write_atomic(&path, |w| {
            w.write_all(b"partial").unwrap();
            panic!("simulated panic");
        });
    }));
    assert!(r.is_err());
    assert_eq!(std::fs::read(&path).unwrap(), b"old content");
    assert_eq!(dir.entries(), vec!["out.bin".to_string()]);

    // A successful write replaces the content and leaves only the target.
    write_atomic(&path, |w| {
        w.write_all(b"new").map_err(|e| Error::Write {
            path: path.clone(),
            reason: e.to_string(),
        })
    })
    .unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), b"new");
    assert_eq!(dir.entries(), vec!["out.bin".to_string()]);
}

#[test]
fn write_to_empty_path_is_error() {
    let r = write_atomic(Path::new(""), |_| Ok(()));
    assert!(matches!(r, Err(Error::Write { .. })), "{r:?}");
}

#[cfg(unix)]
#[test]
fn atomic_write_follows_symlinks_keeps_devices_and_clears_stale_temporaries() {
    use std::io::Write;
    let dir = TempDir::new("atomic-special");
    let write = |path: &Path, data: &'static [u8]| {
        write_atomic(path, move |w| {
            w.write_all(data).unwrap();
            Ok(())
        })
    };
    // A symlink: the file it points to gets the content, the link stays.
    let real = dir.join("real.bin");
    let link = dir.join("link.bin");
    std::fs::write(&real, b"old").unwrap();
    std::os::unix::fs::symlink("real.bin", &link).unwrap();
    write(&link, b"new").unwrap();
    assert!(std::fs::symlink_metadata(&link)
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(std::fs::read(&real).unwrap(), b"new");
    // A device is written to, not replaced.
    write(Path::new("/dev/null"), b"discarded").unwrap();
    use std::os::unix::fs::FileTypeExt;
    assert!(std::fs::metadata("/dev/null")
        .unwrap()
        .file_type()
        .is_char_device());
    // A temporary file of a process that is gone is removed by the next write to the
    // same target; one of a running process (pid 1) is kept.
    if Path::new("/proc/self").exists() {
        let stale = dir.join(".out.bin.4000000000.0.tmp");
        let live = dir.join(".out.bin.1.0.tmp");
        std::fs::write(&stale, b"partial").unwrap();
        std::fs::write(&live, b"partial").unwrap();
        write(&dir.join("out.bin"), b"data").unwrap();
        assert!(!stale.exists());
        assert!(live.exists());
    }
}

/// Several outputs are written all or nothing: when one cannot be written, the others
/// (which existed before) keep their old content and no temporary file is left.
#[test]
fn several_files_are_written_all_or_nothing() {
    use texsyn::image_io::write_files_atomic;
    let dir = TempDir::new("all-or-nothing");
    let a = dir.join("a.bin");
    std::fs::write(&a, b"old").unwrap();
    let missing = dir.join("no-such-dir").join("b.bin");
    let e = write_files_atomic(&[(&a, b"new"), (&missing, b"b")]).unwrap_err();
    assert!(matches!(e, Error::Write { .. }), "{e}");
    assert_eq!(std::fs::read(&a).unwrap(), b"old");
    assert_eq!(dir.entries(), vec!["a.bin".to_string()]);

    let b = dir.join("b.bin");
    write_files_atomic(&[(&a, b"new"), (&b, b"b")]).unwrap();
    assert_eq!(std::fs::read(&a).unwrap(), b"new");
    assert_eq!(std::fs::read(&b).unwrap(), b"b");
    assert_eq!(
        dir.entries(),
        vec!["a.bin".to_string(), "b.bin".to_string()]
    );
}
