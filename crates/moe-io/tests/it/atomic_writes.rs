//! Writers are atomic: a failed write leaves nothing behind, and readers never see a partial
//! file.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};

use moe_geom::Point3;
use moe_io::{
    IoError, PlyData, write_atomic, write_csv, write_json, write_mesh, write_obj, write_ply,
};

use crate::{entries, octahedron, scratch};

#[test]
fn writers_into_a_missing_directory_fail_and_create_nothing() {
    let dir = scratch("missing-dir");
    let missing = dir.join("not-there");
    let mesh = octahedron(1.0);
    let results: Vec<(&str, Result<(), IoError>)> = vec![
        ("obj", write_obj(&missing.join("m.obj"), &mesh)),
        ("mesh", write_mesh(&missing.join("m.ply"), &mesh)),
        (
            "ply",
            write_ply(&missing.join("m.ply"), &PlyData::from_mesh(&mesh)),
        ),
        ("json", write_json(&missing.join("a.json"), &[1.0, 2.0])),
        (
            "csv",
            write_csv(
                &missing.join("a.csv"),
                &["x", "y", "z"],
                &[vec![1.0, 2.0, 3.0]],
            ),
        ),
        ("atomic", write_atomic(&missing.join("a.bin"), b"x")),
    ];
    for (what, r) in results {
        match r {
            Err(IoError::MissingDirectory { dir: d, path }) => {
                assert_eq!(d, missing, "{what}");
                assert!(path.starts_with(&missing), "{what}");
            }
            other => panic!("{what}: expected MissingDirectory, got {other:?}"),
        }
    }
    assert!(entries(&dir).is_empty(), "{:?}", entries(&dir));
}

#[test]
fn failed_writes_keep_the_previous_file_and_leave_no_temporaries() {
    let dir = scratch("keep-previous");
    let ply = dir.join("c.ply");
    let good = PlyData::from_mesh(&octahedron(1.0));
    write_ply(&ply, &good).unwrap();
    let before = std::fs::read(&ply).unwrap();

    let mut bad = good.clone();
    bad.points[2] = Point3::new(f64::NAN, 0.0, 0.0);
    assert!(matches!(
        write_ply(&ply, &bad),
        Err(IoError::InvalidData { .. })
    ));
    bad = good.clone();
    bad.scalars = vec![("p".into(), vec![0.5])];
    assert!(matches!(
        write_ply(&ply, &bad),
        Err(IoError::InvalidData { .. })
    ));
    assert_eq!(std::fs::read(&ply).unwrap(), before);

    let csv = dir.join("t.csv");
    let e = write_csv(
        &csv,
        &["x", "y"],
        &[vec![1.0, 2.0], vec![3.0, f64::INFINITY]],
    )
    .unwrap_err();
    assert!(e.to_string().contains("row 2, column 2"), "{e}");
    let map: std::collections::BTreeMap<(u8, u8), u8> = [((1, 2), 3)].into();
    assert!(matches!(
        write_json(&dir.join("m.json"), &map),
        Err(IoError::Serialize { .. })
    ));
    assert_eq!(entries(&dir), vec!["c.ply".to_string()]);
}

#[test]
fn concurrent_readers_only_ever_see_complete_files() {
    let dir = scratch("no-partial");
    let target = dir.join("big.bin");
    let a = vec![b'a'; 1 << 20];
    let b = vec![b'b'; 3 << 19];
    write_atomic(&target, &a).unwrap();
    let done = Arc::new(AtomicBool::new(false));
    let seen = Arc::new(Mutex::new((0usize, Vec::<String>::new())));
    let reader = {
        let (done, seen, target, a, b) = (
            done.clone(),
            seen.clone(),
            target.clone(),
            a.clone(),
            b.clone(),
        );
        std::thread::spawn(move || {
            while !done.load(Ordering::Acquire) {
                let bytes = std::fs::read(&target).expect("the target always exists");
                let mut s = seen.lock().unwrap();
                s.0 += 1;
                if bytes != a && bytes != b {
                    s.1.push(format!(
                        "saw a {}-byte file that is neither version",
                        bytes.len()
                    ));
                }
            }
        })
    };
    for i in 0..40 {
        write_atomic(&target, if i % 2 == 0 { &b } else { &a }).unwrap();
    }
    done.store(true, Ordering::Release);
    reader.join().unwrap();
    let s = seen.lock().unwrap();
    assert!(s.1.is_empty(), "{:?}", s.1);
    assert!(s.0 > 0);
    assert_eq!(std::fs::read(&target).unwrap(), a);
    assert_eq!(entries(&dir), vec!["big.bin".to_string()]);
}
