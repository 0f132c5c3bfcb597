//! The Replica ground-truth cloud's PLY file (`ROOT/ground_truth/<scene>.ply`):
//! vertex x y z (float), sem inst (int), in ASCII or binary little-endian;
//! read for the evaluation, written by the test fixtures.

use std::io::{BufRead, BufReader, Read, Write};
use std::path::Path;

use nalgebra::Point3;

use super::{ferr, ReplicaError};

/// Ground-truth cloud: points with (sem, inst).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct GroundTruthCloud {
    pub points: Vec<Point3<f32>>,
    pub sem: Vec<i64>,
    pub inst: Vec<i64>,
}

/// Writes the cloud as a binary little-endian PLY: x y z float, sem inst int.
pub fn write_gt_ply(path: &Path, gt: &GroundTruthCloud) -> Result<(), ReplicaError> {
    let f = std::fs::File::create(path).map_err(|e| ferr(path, e))?;
    let mut w = std::io::BufWriter::new(f);
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment opennav ground truth (sem: class id, inst: instance id)\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty int sem\nproperty int inst\nend_header\n",
        gt.points.len()
    );
    let mut buf = header.into_bytes();
    for ((p, s), i) in gt.points.iter().zip(&gt.sem).zip(&gt.inst) {
        for c in [p.x, p.y, p.z] {
            buf.extend_from_slice(&c.to_le_bytes());
        }
        buf.extend_from_slice(&(*s as i32).to_le_bytes());
        buf.extend_from_slice(&(*i as i32).to_le_bytes());
    }
    w.write_all(&buf)
        .and_then(|_| w.flush())
        .map_err(|e| ferr(path, e))
}

#[derive(Clone, Copy, PartialEq)]
enum PlyType {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl PlyType {
    fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "char" | "int8" => PlyType::I8,
            "uchar" | "uint8" => PlyType::U8,
            "short" | "int16" => PlyType::I16,
            "ushort" | "uint16" => PlyType::U16,
            "int" | "int32" => PlyType::I32,
            "uint" | "uint32" => PlyType::U32,
            "float" | "float32" => PlyType::F32,
            "double" | "float64" => PlyType::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            PlyType::I8 | PlyType::U8 => 1,
            PlyType::I16 | PlyType::U16 => 2,
            PlyType::I32 | PlyType::U32 | PlyType::F32 => 4,
            PlyType::F64 => 8,
        }
    }
    fn read_le(self, b: &[u8]) -> f64 {
        match self {
            PlyType::I8 => b[0] as i8 as f64,
            PlyType::U8 => b[0] as f64,
            PlyType::I16 => i16::from_le_bytes([b[0], b[1]]) as f64,
            PlyType::U16 => u16::from_le_bytes([b[0], b[1]]) as f64,
            PlyType::I32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            PlyType::U32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            PlyType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64,
            PlyType::F64 => f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]),
        }
    }
}

/// Reads a ground-truth PLY (ASCII or binary little-endian) whose vertices
/// have x, y, z, sem and inst (other scalar properties are skipped).
pub fn read_gt_ply(path: &Path) -> Result<GroundTruthCloud, ReplicaError> {
    let f = std::fs::File::open(path).map_err(|e| ferr(path, e))?;
    let mut r = BufReader::new(f);
    let mut line = String::new();
    let mut format = String::new();
    let mut n = 0usize;
    let mut props: Vec<(String, PlyType)> = Vec::new();
    let mut in_vertex = false;
    loop {
        line.clear();
        if r.read_line(&mut line).map_err(|e| ferr(path, e))? == 0 {
            return Err(ferr(path, "PLY header has no end_header"));
        }
        let t: Vec<&str> = line.split_whitespace().collect();
        match t.as_slice() {
            ["end_header"] => break,
            ["format", f, _] => format = f.to_string(),
            ["element", "vertex", c] => {
                n = c
                    .parse()
                    .map_err(|_| ferr(path, format!("vertex count `{c}`")))?;
                in_vertex = true;
            }
            ["element", ..] => in_vertex = false,
            ["property", "list", ..] if in_vertex => {
                return Err(ferr(path, "list properties on vertices are not supported"))
            }
            ["property", ty, name] if in_vertex => {
                let ty = PlyType::parse(ty)
                    .ok_or_else(|| ferr(path, format!("property type `{ty}`")))?;
                props.push((name.to_string(), ty));
            }
            _ => {}
        }
    }
    let col = |name: &str| {
        props
            .iter()
            .position(|(p, _)| p == name)
            .ok_or_else(|| ferr(path, format!("vertex property `{name}` missing")))
    };
    let (ix, iy, iz, is, ii) = (col("x")?, col("y")?, col("z")?, col("sem")?, col("inst")?);
    let mut gt = GroundTruthCloud {
        points: Vec::with_capacity(n),
        sem: Vec::with_capacity(n),
        inst: Vec::with_capacity(n),
    };
    let mut push = |vals: &[f64]| {
        gt.points.push(Point3::new(
            vals[ix] as f32,
            vals[iy] as f32,
            vals[iz] as f32,
        ));
        gt.sem.push(vals[is] as i64);
        gt.inst.push(vals[ii] as i64);
    };
    match format.as_str() {
        "binary_little_endian" => {
            let stride: usize = props.iter().map(|(_, t)| t.size()).sum();
            let mut buf = vec![0u8; stride];
            let mut vals = vec![0.0f64; props.len()];
            for k in 0..n {
                r.read_exact(&mut buf)
                    .map_err(|e| ferr(path, format!("vertex {k}: {e}")))?;
                let mut off = 0;
                for (j, (_, t)) in props.iter().enumerate() {
                    vals[j] = t.read_le(&buf[off..off + t.size()]);
                    off += t.size();
                }
                push(&vals);
            }
        }
        "ascii" => {
            for k in 0..n {
                line.clear();
                if r.read_line(&mut line).map_err(|e| ferr(path, e))? == 0 {
                    return Err(ferr(path, format!("{n} vertices announced, {k} found")));
                }
                let vals: Vec<f64> = line
                    .split_whitespace()
                    .map(|x| x.parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|e| ferr(path, format!("vertex {k}: {e}")))?;
                if vals.len() < props.len() {
                    return Err(ferr(
                        path,
                        format!(
                            "vertex {k}: {} values, expected {}",
                            vals.len(),
                            props.len()
                        ),
                    ));
                }
                push(&vals);
            }
        }
        other => {
            return Err(ferr(
                path,
                format!("PLY format `{other}` not supported (ascii, binary_little_endian)"),
            ))
        }
    }
    Ok(gt)
}
