//! A small, defensive reader for MATLAB v5 MAT-files (the format of `save -v5`/`-v7`).
//!
//! Reads numeric arrays of every storage type (converted to `f64`), complex parts, char
//! arrays, logical arrays and (nested) 1x1 structs; everything else (cells, sparse matrices,
//! class objects, MCOS opaque objects such as a `tf`) is kept as [`MatValue::Other`] without
//! failing. `miCOMPRESSED` elements (v7 files) are inflated with zlib. All reads are
//! bounds-checked: a truncated or corrupt file gives an [`ImportError`], never a panic.
//!
//! The `matfile` crate was tried first: it rejects the FdiTools multisine files as a whole
//! (it has no case for the opaque class of their MATLAB `tf` object) and has no structs.

use super::ImportError;
use std::collections::BTreeMap;
use std::io::Read;
use std::path::Path;

// Data types of data elements (MAT-File Format, table 1-1).
const MI_INT8: u32 = 1;
const MI_UINT8: u32 = 2;
const MI_INT16: u32 = 3;
const MI_UINT16: u32 = 4;
const MI_INT32: u32 = 5;
const MI_UINT32: u32 = 6;
const MI_SINGLE: u32 = 7;
const MI_DOUBLE: u32 = 9;
const MI_INT64: u32 = 12;
const MI_UINT64: u32 = 13;
const MI_MATRIX: u32 = 14;
const MI_COMPRESSED: u32 = 15;
const MI_UTF8: u32 = 16;
const MI_UTF16: u32 = 17;
const MI_UTF32: u32 = 18;

// Array classes (MAT-File Format, table 1-3), plus the undocumented opaque class 17.
const MX_CELL: u8 = 1;
const MX_STRUCT: u8 = 2;
const MX_OBJECT: u8 = 3;
const MX_CHAR: u8 = 4;
const MX_SPARSE: u8 = 5;
const MX_DOUBLE: u8 = 6;
const MX_UINT64: u8 = 15;
const MX_FUNCTION: u8 = 16;
const MX_OPAQUE: u8 = 17;

/// Deepest struct nesting followed; deeper values become [`MatValue::Other`].
const MAX_DEPTH: usize = 32;
/// Largest inflated size of one `miCOMPRESSED` element [bytes].
const MAX_INFLATED: u64 = 1 << 31;
/// Most an `miCOMPRESSED` element may inflate to, as a multiple of its compressed size
/// (beyond [`MIN_INFLATE_LIMIT`]): the reader's memory stays a small multiple of its input
/// (issue 16). Measured data compress 1.06 to 1.34 times (the MAT files of ../shared/data:
/// F16, EMPS, the motor bench; 6.6 for a 549-byte element); a zlib bomb inflates about
/// 1000 times.
const MAX_INFLATE_RATIO: u64 = 8;
/// An element may always inflate to this much [bytes] (small elements of few numbers
/// compress better than the ratio).
const MIN_INFLATE_LIMIT: u64 = 4 << 20;

/// One value of a MAT-file.
#[derive(Debug, Clone, PartialEq)]
pub enum MatValue {
    /// A numeric or logical array, any storage type converted to `f64`.
    Numeric {
        /// MATLAB dimensions, e.g. `[50000, 1]` for a column vector.
        dims: Vec<usize>,
        /// Real part in MATLAB (column-major) order: element `(i, j)` of an `r x c` matrix
        /// is `data[i + j * r]`.
        data: Vec<f64>,
        /// Imaginary part, same layout, for complex arrays.
        imag: Option<Vec<f64>>,
    },
    /// A char array; rows of a multi-row char matrix are joined with `'\n'`.
    Char(String),
    /// A 1x1 struct: field name -> value.
    Struct(BTreeMap<String, MatValue>),
    /// Anything not read (cell, sparse, object, opaque MCOS object, struct array, ...);
    /// the text says what it was.
    Other(String),
}

impl MatValue {
    /// The value at a dotted field path below this one (`"harm.fs"`); `""` is `self`.
    pub fn get(&self, field_path: &str) -> Option<&MatValue> {
        let mut v = self;
        for part in field_path.split('.').filter(|p| !p.is_empty()) {
            match v {
                MatValue::Struct(fields) => v = fields.get(part)?,
                _ => return None,
            }
        }
        Some(v)
    }

    /// The single real number of a 1x1 numeric value.
    pub fn as_scalar(&self) -> Option<f64> {
        match self {
            MatValue::Numeric { data, .. } if data.len() == 1 => Some(data[0]),
            _ => None,
        }
    }

    /// Dimensions of a numeric value.
    pub fn dims(&self) -> Option<&[usize]> {
        match self {
            MatValue::Numeric { dims, .. } => Some(dims),
            _ => None,
        }
    }

    /// Short description of the class and shape, for messages (`"numeric 50000x1"`).
    pub fn describe(&self) -> String {
        match self {
            MatValue::Numeric { dims, imag, .. } => format!(
                "{}numeric {}",
                if imag.is_some() { "complex " } else { "" },
                dims_text(dims)
            ),
            MatValue::Char(s) => format!("char '{s}'"),
            MatValue::Struct(f) => format!("struct with {} fields", f.len()),
            MatValue::Other(what) => what.clone(),
        }
    }
}

/// `[3, 1, 7]` -> `"3x1x7"`.
pub fn dims_text(dims: &[usize]) -> String {
    dims.iter()
        .map(|d| d.to_string())
        .collect::<Vec<_>>()
        .join("x")
}

/// The named variables of a MAT v5 file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct MatFile {
    /// The 116-byte descriptive text of the header, trimmed.
    pub header_text: String,
    /// Top-level variables by name (unnamed elements such as MATLAB's hidden function
    /// workspace are left out).
    pub vars: BTreeMap<String, MatValue>,
}

impl MatFile {
    /// Reads and parses the file at `path`.
    pub fn read(path: &Path) -> Result<MatFile, ImportError> {
        let bytes = std::fs::read(path).map_err(|source| ImportError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        MatFile::parse(&bytes, path)
    }

    /// Parses the bytes of a MAT v5 file; `path` is used in error messages only.
    pub fn parse(bytes: &[u8], path: &Path) -> Result<MatFile, ImportError> {
        let not_mat = |reason: String| ImportError::NotMat5 {
            path: path.to_path_buf(),
            reason,
        };
        if bytes.len() < 128 {
            return Err(not_mat(format!(
                "{} bytes, shorter than the 128-byte header",
                bytes.len()
            )));
        }
        let endian = match &bytes[126..128] {
            b"IM" => Endian::Little,
            b"MI" => Endian::Big,
            other => {
                return Err(not_mat(format!(
                    "endian indicator {other:?} is neither \"IM\" nor \"MI\""
                )))
            }
        };
        let version = endian.u16([bytes[124], bytes[125]]);
        if version != 0x0100 {
            return Err(not_mat(format!(
                "header version 0x{version:04x} (v7.3/HDF5 files are not supported)"
            )));
        }
        let header_text = String::from_utf8_lossy(&bytes[..116])
            .trim_end_matches(['\0', ' '])
            .to_string();
        let mut vars = BTreeMap::new();
        let corrupt = |variable: Option<String>, e: Fault| ImportError::Corrupt {
            path: path.to_path_buf(),
            variable,
            offset: e.offset,
            reason: e.reason,
        };
        let mut pos = 128;
        while bytes.len() - pos >= 8 {
            let el = read_element(bytes, pos, endian).map_err(|e| corrupt(None, e))?;
            match el.ty {
                MI_MATRIX => {
                    let (name, value) = parse_matrix(el.data, endian, 0)
                        .map_err(|e| corrupt(peek_name(el.data, endian), e.shift(el.start)))?;
                    if !name.is_empty() {
                        vars.insert(name, value);
                    }
                }
                MI_COMPRESSED => {
                    let inflated = inflate(el.data).map_err(|reason| {
                        corrupt(
                            None,
                            Fault {
                                offset: el.start,
                                reason: format!("miCOMPRESSED element: {reason}"),
                            },
                        )
                    })?;
                    let mut ipos = 0;
                    while inflated.len() - ipos >= 8 {
                        let inner = read_element(&inflated, ipos, endian)
                            .map_err(|e| corrupt(None, e.inflated(el.start)))?;
                        if inner.ty == MI_MATRIX {
                            let (name, value) =
                                parse_matrix(inner.data, endian, 0).map_err(|e| {
                                    corrupt(
                                        peek_name(inner.data, endian),
                                        e.shift(inner.start).inflated(el.start),
                                    )
                                })?;
                            if !name.is_empty() {
                                vars.insert(name, value);
                            }
                        }
                        ipos = inner.next;
                    }
                }
                _ => {} // unknown top-level element: skipped
            }
            pos = el.next;
        }
        if bytes[pos..].iter().any(|&b| b != 0) {
            return Err(corrupt(
                None,
                Fault::new(
                    pos,
                    format!(
                        "{} trailing bytes (truncated element tag?)",
                        bytes.len() - pos
                    ),
                ),
            ));
        }
        Ok(MatFile { header_text, vars })
    }

    /// The value at a dotted path: a variable name, optionally followed by struct fields
    /// (`"ms.harm.fs"`).
    pub fn get(&self, path: &str) -> Option<&MatValue> {
        let (var, rest) = path.split_once('.').unwrap_or((path, ""));
        self.vars.get(var)?.get(rest)
    }

    /// Variable names, sorted.
    pub fn names(&self) -> Vec<String> {
        self.vars.keys().cloned().collect()
    }
}

#[derive(Debug, Clone, Copy)]
enum Endian {
    Little,
    Big,
}

impl Endian {
    fn u16(self, b: [u8; 2]) -> u16 {
        match self {
            Endian::Little => u16::from_le_bytes(b),
            Endian::Big => u16::from_be_bytes(b),
        }
    }
    fn u32(self, b: [u8; 4]) -> u32 {
        match self {
            Endian::Little => u32::from_le_bytes(b),
            Endian::Big => u32::from_be_bytes(b),
        }
    }
    fn u64(self, b: [u8; 8]) -> u64 {
        match self {
            Endian::Little => u64::from_le_bytes(b),
            Endian::Big => u64::from_be_bytes(b),
        }
    }
}

/// Internal parse failure: byte offset (relative to the buffer being parsed) and reason.
#[derive(Debug)]
struct Fault {
    offset: usize,
    reason: String,
}

impl Fault {
    fn new(offset: usize, reason: impl Into<String>) -> Fault {
        Fault {
            offset,
            reason: reason.into(),
        }
    }
    /// Makes the offset relative to the enclosing buffer.
    fn shift(mut self, base: usize) -> Fault {
        self.offset = self.offset.saturating_add(base);
        self
    }
    /// Marks the fault as lying inside the compressed element starting at file byte `at`.
    fn inflated(self, at: usize) -> Fault {
        Fault {
            offset: at,
            reason: format!(
                "in the compressed element (inflated byte {}): {}",
                self.offset, self.reason
            ),
        }
    }
}

/// One data element: type, contents, where its contents start and where the next one does.
struct Element<'a> {
    ty: u32,
    data: &'a [u8],
    start: usize,
    next: usize,
}

fn word(buf: &[u8], pos: usize, endian: Endian) -> Result<u32, Fault> {
    let b = buf
        .get(pos..pos.saturating_add(4))
        .ok_or_else(|| Fault::new(pos, "unexpected end of data"))?;
    Ok(endian.u32([b[0], b[1], b[2], b[3]]))
}

/// Reads the data element at `pos` (both the normal and the small 4-byte format).
fn read_element(buf: &[u8], pos: usize, endian: Endian) -> Result<Element<'_>, Fault> {
    let w0 = word(buf, pos, endian)?;
    if w0 >> 16 != 0 {
        // Small data element: size in the upper, type in the lower 16 bits, data in 4 bytes.
        let n = (w0 >> 16) as usize;
        if n > 4 {
            return Err(Fault::new(pos, format!("small data element of {n} bytes")));
        }
        let start = pos + 4;
        let data = buf
            .get(start..start + n)
            .ok_or_else(|| Fault::new(pos, "unexpected end of data in a small element"))?;
        return Ok(Element {
            ty: w0 & 0xffff,
            data,
            start,
            next: (pos + 8).min(buf.len()),
        });
    }
    let n = word(buf, pos + 4, endian)? as usize;
    let start = pos + 8;
    let end = start
        .checked_add(n)
        .filter(|&e| e <= buf.len())
        .ok_or_else(|| {
            Fault::new(
                pos,
                format!(
                    "element of type {w0} claims {n} bytes, only {} remain (truncated?)",
                    buf.len() - start.min(buf.len())
                ),
            )
        })?;
    let next = if w0 == MI_COMPRESSED {
        end
    } else {
        end.div_ceil(8).saturating_mul(8).min(buf.len())
    };
    Ok(Element {
        ty: w0,
        data: &buf[start..end],
        start,
        next,
    })
}

/// The inflated bytes of a compressed element, at most [`MAX_INFLATE_RATIO`] times its
/// size (at least [`MIN_INFLATE_LIMIT`], at most [`MAX_INFLATED`]).
fn inflate(data: &[u8]) -> Result<Vec<u8>, String> {
    let limit = (data.len() as u64)
        .saturating_mul(MAX_INFLATE_RATIO)
        .clamp(MIN_INFLATE_LIMIT, MAX_INFLATED);
    let dec = libflate::zlib::Decoder::new(data).map_err(|e| format!("zlib: {e}"))?;
    let mut out = Vec::new();
    dec.take(limit + 1)
        .read_to_end(&mut out)
        .map_err(|e| format!("zlib: {e}"))?;
    if out.len() as u64 > limit {
        return Err(format!(
            "inflates to more than {limit} bytes ({MAX_INFLATE_RATIO} times its {} compressed \
             bytes: a zlib bomb?)",
            data.len()
        ));
    }
    Ok(out)
}

/// Best-effort variable name of a matrix element, for error messages.
fn peek_name(data: &[u8], endian: Endian) -> Option<String> {
    let flags = read_element(data, 0, endian).ok()?;
    let class = (word(flags.data, 0, endian).ok()? & 0xff) as u8;
    let mut next = flags.next;
    if class != MX_OPAQUE {
        next = read_element(data, next, endian).ok()?.next;
    }
    let name = read_element(data, next, endian).ok()?;
    Some(String::from_utf8_lossy(name.data).into_owned()).filter(|n| !n.is_empty())
}

/// Parses the contents of an `miMATRIX` element into (name, value).
fn parse_matrix(data: &[u8], endian: Endian, depth: usize) -> Result<(String, MatValue), Fault> {
    if data.is_empty() {
        // MATLAB writes empty cells/fields as zero-length matrix elements.
        return Ok((String::new(), MatValue::Other("empty".into())));
    }
    let flags_el = read_element(data, 0, endian)?;
    if flags_el.data.len() < 8 {
        return Err(Fault::new(
            0,
            "array flags sub-element shorter than 8 bytes",
        ));
    }
    let flags = word(flags_el.data, 0, endian)?;
    let class = (flags & 0xff) as u8;
    let complex = flags & 0x0800 != 0;
    let mut pos = flags_el.next;

    if class == MX_OPAQUE {
        // Opaque (MCOS) object: name, type system, class name, then its data; not decoded.
        let name_el = read_element(data, pos, endian)?;
        let name = String::from_utf8_lossy(name_el.data).into_owned();
        let class_name = read_element(data, name_el.next, endian)
            .ok()
            .and_then(|ts| read_element(data, ts.next, endian).ok())
            .map(|c| String::from_utf8_lossy(c.data).into_owned())
            .unwrap_or_default();
        return Ok((
            name,
            MatValue::Other(format!("opaque object {class_name}").trim().to_string()),
        ));
    }

    let dims_el = read_element(data, pos, endian)?;
    if dims_el.ty != MI_INT32 {
        return Err(Fault::new(
            pos,
            format!("dimensions sub-element has type {}", dims_el.ty),
        ));
    }
    let dims: Vec<usize> = to_f64(&dims_el, endian)
        .map_err(|e| e.shift(dims_el.start))?
        .into_iter()
        .map(|d| if d < 0.0 { Err(d) } else { Ok(d as usize) })
        .collect::<Result<_, _>>()
        .map_err(|d| Fault::new(pos, format!("negative dimension {d}")))?;
    pos = dims_el.next;
    let count = dims
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or_else(|| Fault::new(pos, "dimension product overflows"))?;
    let name_el = read_element(data, pos, endian)?;
    let name = String::from_utf8_lossy(name_el.data).into_owned();
    pos = name_el.next;

    let value = match class {
        MX_DOUBLE..=MX_UINT64 => {
            let re_el = read_element(data, pos, endian)?;
            let re = to_f64(&re_el, endian).map_err(|e| e.shift(re_el.start))?;
            check_count(re.len(), count, &dims, pos, "real")?;
            let imag = if complex {
                let im_el = read_element(data, re_el.next, endian)?;
                let im = to_f64(&im_el, endian).map_err(|e| e.shift(im_el.start))?;
                check_count(im.len(), count, &dims, re_el.next, "imaginary")?;
                Some(im)
            } else {
                None
            };
            MatValue::Numeric {
                dims,
                data: re,
                imag,
            }
        }
        MX_CHAR => {
            let el = read_element(data, pos, endian)?;
            MatValue::Char(decode_chars(&el, &dims, endian).map_err(|e| e.shift(el.start))?)
        }
        MX_STRUCT if count == 1 && depth < MAX_DEPTH => {
            let len_el = read_element(data, pos, endian)?;
            let field_len = word(len_el.data, 0, endian)? as usize;
            let names_el = read_element(data, len_el.next, endian)?;
            if field_len == 0 && !names_el.data.is_empty() {
                return Err(Fault::new(pos, "struct field-name length 0"));
            }
            let field_names: Vec<String> = if field_len == 0 {
                Vec::new()
            } else {
                names_el
                    .data
                    .chunks(field_len)
                    .map(|c| {
                        let end = c.iter().position(|&b| b == 0).unwrap_or(c.len());
                        String::from_utf8_lossy(&c[..end]).into_owned()
                    })
                    .collect()
            };
            let mut fields = BTreeMap::new();
            let mut fpos = names_el.next;
            for field in field_names {
                let el = read_element(data, fpos, endian)?;
                if el.ty != MI_MATRIX {
                    return Err(Fault::new(
                        fpos,
                        format!("struct field `{field}` is element type {}", el.ty),
                    ));
                }
                let (_, v) = parse_matrix(el.data, endian, depth + 1).map_err(|e| Fault {
                    offset: e.offset.saturating_add(el.start),
                    reason: format!("field `{field}`: {}", e.reason),
                })?;
                fields.insert(field, v);
                fpos = el.next;
            }
            MatValue::Struct(fields)
        }
        MX_STRUCT => MatValue::Other(format!("struct array {}", dims_text(&dims))),
        MX_CELL => MatValue::Other(format!("cell {}", dims_text(&dims))),
        MX_OBJECT => MatValue::Other("object".into()),
        MX_SPARSE => MatValue::Other(format!("sparse {}", dims_text(&dims))),
        MX_FUNCTION => MatValue::Other("function handle".into()),
        c => MatValue::Other(format!("class {c}")),
    };
    Ok((name, value))
}

fn check_count(
    got: usize,
    want: usize,
    dims: &[usize],
    pos: usize,
    part: &str,
) -> Result<(), Fault> {
    if got == want {
        Ok(())
    } else {
        Err(Fault::new(
            pos,
            format!(
                "{part} part has {got} values, dimensions {} need {want}",
                dims_text(dims)
            ),
        ))
    }
}

/// Converts the contents of a numeric data element to `f64`.
fn to_f64(el: &Element<'_>, endian: Endian) -> Result<Vec<f64>, Fault> {
    let size = match el.ty {
        MI_INT8 | MI_UINT8 | MI_UTF8 => 1,
        MI_INT16 | MI_UINT16 | MI_UTF16 => 2,
        MI_INT32 | MI_UINT32 | MI_SINGLE | MI_UTF32 => 4,
        MI_DOUBLE | MI_INT64 | MI_UINT64 => 8,
        t => {
            return Err(Fault::new(
                0,
                format!("data element type {t} is not numeric"),
            ))
        }
    };
    if el.data.len() % size != 0 {
        return Err(Fault::new(
            0,
            format!(
                "{} bytes are not a whole number of {size}-byte values",
                el.data.len()
            ),
        ));
    }
    let out = el
        .data
        .chunks_exact(size)
        .map(|b| match el.ty {
            MI_INT8 => b[0] as i8 as f64,
            MI_UINT8 | MI_UTF8 => b[0] as f64,
            MI_INT16 => endian.u16([b[0], b[1]]) as i16 as f64,
            MI_UINT16 | MI_UTF16 => endian.u16([b[0], b[1]]) as f64,
            MI_INT32 => endian.u32([b[0], b[1], b[2], b[3]]) as i32 as f64,
            MI_UINT32 | MI_UTF32 => endian.u32([b[0], b[1], b[2], b[3]]) as f64,
            MI_SINGLE => f32::from_bits(endian.u32([b[0], b[1], b[2], b[3]])) as f64,
            MI_DOUBLE => {
                f64::from_bits(endian.u64([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]))
            }
            MI_INT64 => endian.u64([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]) as i64 as f64,
            _ => endian.u64([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]) as f64,
        })
        .collect();
    Ok(out)
}

/// Decodes a char array (UTF-8/UTF-16/UTF-32 or 8-bit storage), rows joined by `'\n'`.
fn decode_chars(el: &Element<'_>, dims: &[usize], endian: Endian) -> Result<String, Fault> {
    let chars: Vec<char> = match el.ty {
        MI_UTF8 | MI_INT8 | MI_UINT8 => String::from_utf8_lossy(el.data).chars().collect(),
        MI_UINT16 | MI_UTF16 | MI_INT16 => {
            let units: Vec<u16> = el
                .data
                .chunks_exact(2)
                .map(|b| endian.u16([b[0], b[1]]))
                .collect();
            String::from_utf16_lossy(&units).chars().collect()
        }
        MI_UINT32 | MI_UTF32 | MI_INT32 => el
            .data
            .chunks_exact(4)
            .map(|b| char::from_u32(endian.u32([b[0], b[1], b[2], b[3]])).unwrap_or('\u{fffd}'))
            .collect(),
        t => return Err(Fault::new(0, format!("char data of element type {t}"))),
    };
    match dims {
        [rows, cols] if *rows > 1 && rows * cols == chars.len() => Ok((0..*rows)
            .map(|r| (0..*cols).map(|c| chars[r + c * rows]).collect::<String>())
            .collect::<Vec<_>>()
            .join("\n")),
        _ => Ok(chars.into_iter().collect()),
    }
}
