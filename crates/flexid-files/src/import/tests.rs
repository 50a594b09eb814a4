//! Tests of the importers: synthetic MAT files, corrupt input, and the shared data sets
//! (skipped with a message when the shared data folder is absent). Expected values were
//! read from the files with `scipy.io.loadmat`.

use super::*;
use crate::recording::MotionSignal;
use flexid_core::excitation::ExcitationKind;
use std::path::{Path, PathBuf};

/// Path of a shared data file, or `None` (with a printed message) when absent.
fn data_file(rel: &str) -> Option<PathBuf> {
    let p = shared_data_dir().join(rel);
    if p.is_file() {
        Some(p)
    } else {
        eprintln!(
            "skipped: {} not found (set {SHARED_DATA_ENV} to the shared data folder)",
            p.display()
        );
        None
    }
}

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs())
}

fn numeric(v: &MatValue) -> (&[usize], &[f64]) {
    match v {
        MatValue::Numeric { dims, data, .. } => (dims, data),
        other => panic!("expected numeric, got {other:?}"),
    }
}

// ---------- a tiny MAT v5 writer for synthetic files ----------

#[derive(Clone, Copy)]
struct W {
    big: bool,
}

impl W {
    fn u32(self, v: u32) -> [u8; 4] {
        if self.big {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    }
    fn el(self, ty: u32, data: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        out.extend(self.u32(ty));
        out.extend(self.u32(data.len() as u32));
        out.extend(data);
        while out.len() % 8 != 0 {
            out.push(0);
        }
        out
    }
    fn small(self, ty: u32, data: &[u8]) -> Vec<u8> {
        let mut out = Vec::new();
        out.extend(self.u32(((data.len() as u32) << 16) | ty));
        let mut d = data.to_vec();
        d.resize(4, 0);
        out.extend(d);
        out
    }
    fn matrix(self, flags: u32, dims: &[i32], name: &str, body: &[Vec<u8>]) -> Vec<u8> {
        let mut c = Vec::new();
        let mut f = self.u32(flags).to_vec();
        f.extend([0u8; 4]);
        c.extend(self.el(6, &f));
        let d: Vec<u8> = dims.iter().flat_map(|&x| self.u32(x as u32)).collect();
        c.extend(self.el(5, &d));
        c.extend(self.el(1, name.as_bytes()));
        for b in body {
            c.extend(b);
        }
        self.el(14, &c)
    }
    fn doubles(self, v: &[f64]) -> Vec<u8> {
        let d: Vec<u8> = v
            .iter()
            .flat_map(|x| {
                if self.big {
                    x.to_be_bytes()
                } else {
                    x.to_le_bytes()
                }
            })
            .collect();
        self.el(9, &d)
    }
    fn header(self) -> Vec<u8> {
        let mut h = b"MATLAB 5.0 MAT-file, synthetic test".to_vec();
        h.resize(116, b' ');
        h.extend([0u8; 8]);
        if self.big {
            h.extend([0x01, 0x00]);
            h.extend(b"MI");
        } else {
            h.extend([0x00, 0x01]);
            h.extend(b"IM");
        }
        h
    }
}

fn synthetic(big: bool) -> Vec<u8> {
    let w = W { big };
    let mut f = w.header();
    // 2x2 double matrix [1 3; 2 4]
    f.extend(w.matrix(6, &[2, 2], "m", &[w.doubles(&[1.0, 2.0, 3.0, 4.0])]));
    // int16 class, stored as miINT16 in the small element format: [-5, 7]
    let i16s: Vec<u8> = [-5i16, 7]
        .iter()
        .flat_map(|x| {
            if big {
                x.to_be_bytes()
            } else {
                x.to_le_bytes()
            }
        })
        .collect();
    f.extend(w.matrix(10, &[1, 2], "k", &[w.small(3, &i16s)]));
    // complex double 1x2, real stored as uint8
    f.extend(w.matrix(
        6 | 0x0800,
        &[1, 2],
        "z",
        &[w.el(2, &[1, 2]), w.doubles(&[-1.0, 0.5])],
    ));
    // struct s.a = 2.5, s.sub.fs = 1000 (uint16)
    let fs_el = w.el(
        4,
        &(if big {
            1000u16.to_be_bytes()
        } else {
            1000u16.to_le_bytes()
        }),
    );
    let sub = w.matrix(
        2,
        &[1, 1],
        "",
        &[
            w.small(5, &w.u32(3)),
            w.el(1, b"fs\0"),
            w.matrix(12, &[1, 1], "", &[fs_el]),
        ],
    );
    let a = w.matrix(6, &[1, 1], "", &[w.doubles(&[2.5])]);
    let mut names = b"a\0\0\0".to_vec();
    names.extend(b"sub\0");
    f.extend(w.matrix(
        2,
        &[1, 1],
        "s",
        &[w.small(5, &w.u32(4)), w.el(1, &names), a, sub],
    ));
    // char 'ab' as uint16
    let ch: Vec<u8> = ['a', 'b']
        .iter()
        .flat_map(|&c| {
            if big {
                (c as u16).to_be_bytes()
            } else {
                (c as u16).to_le_bytes()
            }
        })
        .collect();
    f.extend(w.matrix(4, &[1, 2], "c", &[w.el(4, &ch)]));
    // a cell (kept as Other)
    f.extend(w.matrix(
        1,
        &[1, 1],
        "cellvar",
        &[w.matrix(6, &[1, 1], "", &[w.doubles(&[9.0])])],
    ));
    // a compressed 3x1 double vector
    let inner = w.matrix(6, &[3, 1], "zipped", &[w.doubles(&[0.25, -8.0, 1e300])]);
    let mut enc = libflate::zlib::Encoder::new(Vec::new()).unwrap();
    std::io::Write::write_all(&mut enc, &inner).unwrap();
    let zipped = enc.finish().into_result().unwrap();
    f.extend(w.u32(15));
    f.extend(w.u32(zipped.len() as u32));
    f.extend(zipped);
    f
}

#[test]
fn synthetic_files_both_endians() {
    for big in [false, true] {
        let bytes = synthetic(big);
        let m = MatFile::parse(&bytes, Path::new("synthetic.mat")).unwrap();
        assert_eq!(m.names(), ["c", "cellvar", "k", "m", "s", "z", "zipped"]);
        let (dims, data) = numeric(&m.vars["m"]);
        assert_eq!((dims, data), (&[2usize, 2][..], &[1.0, 2.0, 3.0, 4.0][..]));
        assert_eq!(numeric(&m.vars["k"]).1, &[-5.0, 7.0]);
        match &m.vars["z"] {
            MatValue::Numeric { data, imag, .. } => {
                assert_eq!(data, &[1.0, 2.0]);
                assert_eq!(imag.as_deref(), Some(&[-1.0, 0.5][..]));
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(m.get("s.a").and_then(MatValue::as_scalar), Some(2.5));
        assert_eq!(
            m.get("s.sub.fs").and_then(MatValue::as_scalar),
            Some(1000.0)
        );
        assert_eq!(m.get("s.nope"), None);
        assert_eq!(m.vars["c"], MatValue::Char("ab".into()));
        assert!(matches!(&m.vars["cellvar"], MatValue::Other(s) if s.starts_with("cell")));
        assert_eq!(numeric(&m.vars["zipped"]).1, &[0.25, -8.0, 1e300]);
        // Every prefix of the file is either an error or a subset, never a panic.
        for n in 0..bytes.len() {
            let _ = MatFile::parse(&bytes[..n], Path::new("prefix.mat"));
        }
    }
}

#[test]
fn spec_signal_channels_and_errors() {
    let w = W { big: false };
    let mut f = w.header();
    // 2 channels x 3 samples, and a 3 samples x 2 channels matrix
    f.extend(w.matrix(
        6,
        &[2, 3],
        "wide",
        &[w.doubles(&[1., 10., 2., 20., 3., 30.])],
    ));
    f.extend(w.matrix(
        6,
        &[3, 2],
        "tall",
        &[w.doubles(&[1., 2., 3., 10., 20., 30.])],
    ));
    let m = MatFile::parse(&f, Path::new("x.mat")).unwrap();
    let p = Path::new("x.mat");
    assert_eq!(signal(&m, p, "wide", Some(1)).unwrap(), [10., 20., 30.]);
    assert_eq!(signal(&m, p, "tall", Some(1)).unwrap(), [10., 20., 30.]);
    let e = signal(&m, p, "tall", None).unwrap_err();
    assert!(matches!(e, ImportError::BadVariable { .. }), "{e}");
    let e = signal(&m, p, "tall", Some(2)).unwrap_err();
    assert!(e.to_string().contains("no channel 2"), "{e}");
    let e = signal(&m, p, "nope", None).unwrap_err();
    assert!(
        e.to_string().contains("nope") && e.to_string().contains("tall"),
        "{e}"
    );
}

#[test]
fn garbage_and_bad_headers_are_errors() {
    let p = Path::new("garbage.mat");
    assert!(matches!(
        MatFile::parse(b"short", p),
        Err(ImportError::NotMat5 { .. })
    ));
    assert!(matches!(
        MatFile::parse(&[0u8; 200], p),
        Err(ImportError::NotMat5 { .. })
    ));
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        state
    };
    let header = W { big: false }.header();
    for round in 0..300 {
        let len = 136 + (next() % 2048) as usize;
        let mut bytes = header.clone();
        while bytes.len() < len {
            bytes.push(next() as u8);
        }
        if round % 3 == 0 {
            // plausible tag: miMATRIX or miCOMPRESSED with a small size
            bytes[128..132].copy_from_slice(&(14 + (round % 2) as u32).to_le_bytes());
            bytes[132..136].copy_from_slice(&((next() % 512) as u32).to_le_bytes());
        }
        let _ = MatFile::parse(&bytes, p); // must not panic
    }
    let e = MatFile::read(Path::new("/nonexistent/flexid/x.mat")).unwrap_err();
    assert!(matches!(e, ImportError::Io { .. }) && e.to_string().contains("x.mat"));
}

// ---------- shared data sets ----------

#[test]
fn real_files_truncated_or_mutated_give_errors_not_panics() {
    let Some(path) = data_file("fditools-motor-bench/MultisineTypeA.mat") else {
        return;
    };
    let bytes = std::fs::read(&path).unwrap();
    for n in [
        0,
        100,
        127,
        130,
        136,
        1000,
        50_000,
        bytes.len() / 2,
        bytes.len() - 1,
    ] {
        let r = MatFile::parse(&bytes[..n], &path);
        let e = r.expect_err("truncated file must not parse");
        assert!(e.to_string().contains("MultisineTypeA.mat"), "{e}");
    }
    // A small real file with compressed nested structs: all prefixes and single-byte
    // mutations must be handled without panic.
    if let Some(small) = data_file("fditools-motor-bench/ident_python.mat") {
        let bytes = std::fs::read(&small).unwrap();
        for n in 0..bytes.len() {
            let _ = MatFile::parse(&bytes[..n], &small);
        }
        for i in 0..bytes.len() {
            for x in [0x01u8, 0x80, 0xff] {
                let mut b = bytes.clone();
                b[i] ^= x;
                let _ = MatFile::parse(&b, &small);
            }
        }
    }
}

#[test]
fn ident_python_structs() {
    let Some(path) = data_file("fditools-motor-bench/ident_python.mat") else {
        return;
    };
    let m = MatFile::read(&path).unwrap();
    let (dims, a) = numeric(m.get("models.Pv_11.A").unwrap());
    assert_eq!(dims, &[7, 7]);
    assert_eq!(a[0], -2.100774089527743);
    assert!(close(a.iter().sum(), 13412.327551631066, 1e-12));
    assert_eq!(
        m.get("models.Pp_21.Ts").and_then(MatValue::as_scalar),
        Some(0.0)
    );
}

#[test]
fn fditools_type_a() {
    let Some(path) = data_file("fditools-motor-bench/MultisineTypeA.mat") else {
        return;
    };
    let m = MatFile::read(&path).unwrap();
    let (dims, iq) = numeric(&m.vars["iq_adx"]);
    assert_eq!(dims, &[50000, 1]);
    assert_eq!((iq[0], iq[49999]), (10.9882, 13.26831));
    assert!(close(iq.iter().sum(), 7021.455400945, 1e-12));
    let (_, th) = numeric(&m.vars["theta_mx"]);
    assert_eq!((th[0], th[49999]), (-7.456285, -7.500621));
    assert!(close(th.iter().sum(), -371289.81515100005, 1e-12));
    assert_eq!(numeric(&m.vars["xf"]).1[0], 1.388033906741398);
    assert_eq!(m.get("fs").and_then(MatValue::as_scalar), Some(2500.0));
    assert_eq!(m.get("nrofs").and_then(MatValue::as_scalar), Some(2500.0));
    assert_eq!(
        m.get("ms.harm.fs").and_then(MatValue::as_scalar),
        Some(2500.0)
    );
    assert_eq!(
        m.get("ms.harm.fl").and_then(MatValue::as_scalar),
        Some(11.0)
    );
    assert_eq!(
        m.get("ms.nrofs").and_then(MatValue::as_scalar),
        Some(2500.0)
    );
    assert!(matches!(m.get("ms.Hampl"), Some(MatValue::Other(s)) if s.contains("opaque")));
    assert_eq!(m.get("itp"), Some(&MatValue::Char("s".into())));

    let (rel, spec) = preset("fditools-typeA").unwrap();
    let rec = mat_to_recording(&shared_data_dir().join(rel), &spec).unwrap();
    assert_eq!(rec.len(), 50000);
    assert_eq!(rec.sample_rate_hz, 2500.0);
    assert_eq!(rec.time_s[2500], 1.0);
    assert_eq!(rec.position_rad.as_ref().unwrap()[0], -7.456285);
    assert!(rec.velocity_rad_s.is_none() && rec.acceleration_rad_s2.is_none());
    let ex = rec.sidecar.excitation.as_ref().unwrap();
    assert_eq!(ex.kind, ExcitationKind::Multisine);
    assert_eq!(
        (ex.period_samples, ex.periods, ex.transient_periods),
        (2500, 19, 1)
    );
    assert_eq!(ex.excited_lines, (11..=250).collect::<Vec<_>>());
    assert_eq!(ex.band_hz, Some([11.0, 250.0]));
    let src = rec.sidecar.source.as_deref().unwrap();
    assert!(
        src.contains("MultisineTypeA.mat") && src.contains("current iq [A]"),
        "{src}"
    );
    assert_eq!(rec.sidecar.sample_rate_hz, Some(2500.0));

    let (_, spec) = preset("fditools-typeA-load").unwrap();
    let load = mat_to_recording(&path, &spec).unwrap();
    assert_eq!(load.position_rad.as_ref().unwrap()[0], -0.6056647);
    assert_eq!(load.position_rad.as_ref().unwrap()[49999], -0.6376207);
}

#[test]
fn fditools_type_b() {
    let Some(path) = data_file("fditools-motor-bench/MultisineTypeB.mat") else {
        return;
    };
    let (_, spec) = preset("fditools-typeB").unwrap();
    let rec = mat_to_recording(&path, &spec).unwrap();
    assert_eq!(rec.len(), 50000);
    assert_eq!(rec.sample_rate_hz, 2500.0);
    assert_eq!(rec.torque_cmd_nm[0], 9.911647);
    assert_eq!(rec.torque_cmd_nm[49999], 12.98773);
    let th = rec.position_rad.as_ref().unwrap();
    assert_eq!((th[0], th[49999]), (3.571257, 3.526562));
    assert!(close(th.iter().sum(), 179376.18068700001, 1e-12));
    let ex = rec.sidecar.excitation.unwrap();
    assert_eq!(ex.excited_lines, (13..=249).step_by(4).collect::<Vec<_>>());
    assert_eq!(ex.excited_lines.len(), 60);
    assert_eq!((ex.period_samples, ex.periods), (2500, 19));
    // The measured current alone (mean of the steady periods) shows the same 60 lines
    // above 10 % of the largest, far more at 1e-6 (noise).
    let mean = mean_period(&rec.torque_cmd_nm, 2500, 1).unwrap();
    assert_eq!(excited_lines(&mean, 0.1), ex.excited_lines);
    assert!(excited_lines(&mean, 1e-6).len() > 1000);
}

#[test]
fn daisy_robot_arm() {
    let Some(path) = data_file("daisy-robot-arm/robot_arm.dat") else {
        return;
    };
    let rows = read_columns(&path).unwrap();
    assert_eq!(rows.len(), 1024);
    assert!(rows.iter().all(|r| r.len() == 2));
    let rec = daisy_to_recording(&path, 100.0, MotionSignal::Acceleration).unwrap();
    assert_eq!(rec.len(), 1024);
    assert_eq!(rec.torque_cmd_nm[0], 0.22183165);
    assert_eq!(rec.acceleration_rad_s2.as_ref().unwrap()[0], -0.1770363);
    assert_eq!(rec.torque_cmd_nm[1023], 0.29035137);
    assert_eq!(rec.acceleration_rad_s2.as_ref().unwrap()[1023], -0.1671642);
    assert_eq!(rec.time_s[100], 1.0);

    let preset_rec = load_preset("daisy-robot-arm", &shared_data_dir())
        .unwrap()
        .unwrap();
    assert_eq!(preset_rec.torque_cmd_nm, rec.torque_cmd_nm);
    assert_eq!(preset_rec.sample_rate_hz, 100.0);
    let ex = preset_rec.sidecar.excitation.as_ref().unwrap();
    assert_eq!(ex.kind, ExcitationKind::Other);
    assert!(preset_rec
        .sidecar
        .source
        .as_deref()
        .unwrap()
        .contains("assumed"));

    // The MAT twin holds the same numbers.
    if let Some(mat) = data_file("daisy-robot-arm/robot_arm_dat.mat") {
        let spec = MatSpec {
            input_column: Some(0),
            output_column: Some(1),
            sample_rate_hz: Some(100.0),
            ..MatSpec::new("robot_arm_dat", "robot_arm_dat", MotionSignal::Acceleration)
        };
        let r2 = mat_to_recording(&mat, &spec).unwrap();
        assert_eq!(r2.torque_cmd_nm, rec.torque_cmd_nm);
        assert_eq!(r2.acceleration_rad_s2, rec.acceleration_rad_s2);
    }
}

#[test]
fn daisy_text_errors() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bad.dat");
    std::fs::write(&p, "1 2\n3 x\n").unwrap();
    let e = read_columns(&p).unwrap_err();
    assert!(e.to_string().contains("bad.dat:2"), "{e}");
    std::fs::write(&p, "% comment\n1 2\n3 4 5\n").unwrap();
    assert!(matches!(
        read_columns(&p),
        Err(ImportError::Text { line: 3, .. })
    ));
    std::fs::write(&p, "1\n2\n").unwrap();
    assert!(matches!(
        daisy_to_recording(&p, 1.0, MotionSignal::Position),
        Err(ImportError::Spec { .. })
    ));
}

#[test]
fn f16_full_multisine_level1() {
    let Some(path) = data_file("f16-gvt/F16Data_FullMSine_Level1.mat") else {
        return;
    };
    let m = MatFile::read(&path).unwrap();
    assert_eq!(m.names(), ["Acceleration", "Force", "Fs", "Voltage"]);
    assert_eq!(m.vars["Acceleration"].dims(), Some(&[3usize, 73728][..]));
    assert_eq!(m.vars["Force"].dims(), Some(&[1usize, 73728][..]));
    assert_eq!(m.get("Fs").and_then(MatValue::as_scalar), Some(400.0));

    let rec = load_preset("f16", &shared_data_dir()).unwrap().unwrap();
    assert_eq!(rec.len(), 73728);
    assert_eq!(rec.sample_rate_hz, 400.0);
    assert_eq!(rec.torque_cmd_nm[0], 0.9571430573429155);
    assert_eq!(rec.torque_cmd_nm[73727], 2.495097575792043);
    let acc = rec.acceleration_rad_s2.as_ref().unwrap();
    assert_eq!(
        (acc[0], acc[73727]),
        (-0.018391962459601403, 0.009442638098670943)
    );
    assert!(close(acc.iter().sum(), 0.20658975986595784, 1e-9));
    let ex = rec.sidecar.excitation.as_ref().unwrap();
    assert_eq!(
        (ex.period_samples, ex.periods, ex.transient_periods),
        (8192, 8, 1)
    );
    assert_eq!(ex.excited_lines, (41..=307).collect::<Vec<_>>());
    let band = ex.band_hz.unwrap();
    assert!(close(band[0], 2.001953125, 1e-12) && close(band[1], 14.990234375, 1e-12));
}

#[test]
fn f16_special_odd_three_dim_acceleration() {
    let Some(_) = data_file("f16-gvt/F16Data_SpecialOddMSine_Level1_Validation.mat") else {
        return;
    };
    let rec = load_preset("f16-special-odd", &shared_data_dir())
        .unwrap()
        .unwrap();
    assert_eq!(rec.len(), 49152);
    assert_eq!(rec.torque_cmd_nm[0], -16.49257569550892);
    assert_eq!(
        rec.acceleration_rad_s2.as_ref().unwrap()[0],
        -0.164720148860067
    );
    let ex = rec.sidecar.excitation.as_ref().unwrap();
    assert_eq!((ex.period_samples, ex.periods), (16384, 2));
    assert_eq!(ex.excited_lines.len(), 906);
    assert!(ex.excited_lines.iter().all(|k| k % 2 == 1));
    assert_eq!(ex.excited_lines[..3], [41, 43, 47]);
}

#[test]
fn emps_and_every_preset_loads() {
    let dir = shared_data_dir();
    if !dir.is_dir() {
        eprintln!("skipped: {} not found", dir.display());
        return;
    }
    if data_file("emps/DATA_EMPS.mat").is_some() {
        let rec = load_preset("emps", &dir).unwrap().unwrap();
        assert_eq!(rec.len(), 24841);
        // the force in N: gtau [N/V] (35.15065188 in the file) times `vir` [V]
        let gtau = 35.15065188;
        assert!(close(rec.torque_cmd_nm[0], gtau * 2.5386280888756465, 1e-8));
        let qm = rec.position_rad.as_ref().unwrap();
        assert_eq!((qm[0], qm[24840]), (7.45e-06, 0.00361505));
        assert!(close(qm.iter().sum(), 3074.4318380999994, 1e-12));
    }
    for name in PRESET_NAMES {
        let (rel, _) = preset(name).unwrap();
        if dir.join(rel).is_file() {
            let rec = load_preset(name, &dir).unwrap().unwrap();
            assert!(rec.len() > 1000, "{name}");
            assert!(rec.preferred_motion().is_some(), "{name}");
        } else {
            eprintln!("skipped: preset {name}: {rel} not found");
        }
    }
    assert!(preset("no-such-preset").is_none());
    assert!(load_preset("no-such-preset", &dir).unwrap().is_none());
}

/// Issue 16: an `miCOMPRESSED` element inflates to at most 8 times its size (at least
/// 4 MiB): a zlib bomb (6 MiB of zeros in a few kB) is refused naming the ratio, where it
/// was inflated up to 2 GiB whatever its size; a 1 MiB vector of zeros (under the floor)
/// still reads.
#[test]
fn a_zlib_bomb_is_refused_by_its_ratio() {
    let w = W { big: false };
    let file = |values: usize| {
        let inner = w.matrix(
            6,
            &[values as i32, 1],
            "zeros",
            &[w.doubles(&vec![0.0; values])],
        );
        let mut enc = libflate::zlib::Encoder::new(Vec::new()).unwrap();
        std::io::Write::write_all(&mut enc, &inner).unwrap();
        let zipped = enc.finish().into_result().unwrap();
        let mut f = w.header();
        f.extend(w.u32(15));
        f.extend(w.u32(zipped.len() as u32));
        f.extend(zipped);
        f
    };
    let bomb = file(6 << 17); // 6 MiB of doubles
    assert!(bomb.len() < 100_000, "{} bytes", bomb.len());
    let e = MatFile::parse(&bomb, Path::new("bomb.mat"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("bomb.mat") && e.contains("8 times"), "{e}");
    let small = file(1 << 17); // 1 MiB
    let m = MatFile::parse(&small, Path::new("zeros.mat")).unwrap();
    assert_eq!(numeric(&m.vars["zeros"]).1.len(), 1 << 17);
}
