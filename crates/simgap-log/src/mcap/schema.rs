//! ROS 2 message definitions (`ros2msg`, the text rosbag2 stores as a channel's schema) and a
//! CDR decoder driven by them, so any message type can be read and its fields mapped by name.
//!
//! A definition is the message's own fields, then each type it uses after a line of `=` and a
//! `MSG: pkg/Type` line. Field lines are `type name [default]`; constants (`type NAME=value`)
//! and comments are skipped. Types: the primitives (`bool`, `byte`, `char`, `int8`…`uint64`,
//! `float32`, `float64`, `string`, `wstring`, bounded `string<=N`), other messages (`pkg/Type`,
//! `pkg/msg/Type`, or `Type` of the same package; `Header` is `std_msgs/Header`), arrays
//! `T[N]`, sequences `T[]` and bounded sequences `T[<=N]`. `builtin_interfaces/Time` and
//! `Duration` are known without a definition.
//!
//! Decoding never trusts a count: a sequence or fixed array of `n` elements is only allocated
//! when `n` times the smallest encoded element fits in the bytes that remain; nesting is
//! limited to [`MAX_DEPTH`] and recursive definitions are refused.

use std::collections::HashMap;

use super::cdr::{encapsulation, CdrError, CdrReader};

/// Deepest nesting of message types accepted.
pub const MAX_DEPTH: usize = 16;

/// A primitive type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Primitive {
    /// `bool`.
    Bool,
    /// `byte`, `uint8`, `char`.
    U8,
    /// `int8`.
    I8,
    /// `int16`.
    I16,
    /// `uint16`.
    U16,
    /// `int32`.
    I32,
    /// `uint32`.
    U32,
    /// `int64`.
    I64,
    /// `uint64`.
    U64,
    /// `float32`.
    F32,
    /// `float64`.
    F64,
    /// `string` (bounded or not).
    String,
    /// `wstring` (UTF-32 code units, as Fast-CDR writes them).
    WString,
}

impl Primitive {
    fn parse(s: &str) -> Option<Primitive> {
        let base = s.split("<=").next().unwrap_or(s);
        Some(match base {
            "bool" => Primitive::Bool,
            "byte" | "uint8" | "char" => Primitive::U8,
            "int8" => Primitive::I8,
            "int16" => Primitive::I16,
            "uint16" => Primitive::U16,
            "int32" => Primitive::I32,
            "uint32" => Primitive::U32,
            "int64" => Primitive::I64,
            "uint64" => Primitive::U64,
            "float32" => Primitive::F32,
            "float64" => Primitive::F64,
            "string" => Primitive::String,
            "wstring" => Primitive::WString,
            _ => return None,
        })
    }

    /// Encoded size (the length word for strings).
    fn size(self) -> usize {
        match self {
            Primitive::Bool | Primitive::U8 | Primitive::I8 => 1,
            Primitive::I16 | Primitive::U16 => 2,
            Primitive::I32 | Primitive::U32 | Primitive::F32 | Primitive::String | Primitive::WString => 4,
            Primitive::I64 | Primitive::U64 | Primitive::F64 => 8,
        }
    }
}

/// The type of a field's element.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ElemType {
    /// A primitive.
    Primitive(Primitive),
    /// A message, by index in [`Schema`].
    Message(usize),
}

/// Single value, fixed-size array, or sequence.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Arity {
    /// One value.
    Single,
    /// `T[N]`: exactly N values, no count on the wire.
    Fixed(usize),
    /// `T[]` or `T[<=N]`: a `u32` count then the values.
    Sequence,
}

/// A field of a message definition.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Field {
    /// Field name.
    pub name: String,
    /// Element type.
    pub elem: ElemType,
    /// Single, array or sequence.
    pub arity: Arity,
}

/// A message definition.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MessageDef {
    /// `pkg/Type` (without `/msg/`).
    pub name: String,
    /// Fields in wire order.
    pub fields: Vec<Field>,
    /// The fewest bytes one value of this message takes on the wire (at least 1).
    min_size: usize,
}

/// A parsed definition: the root message (index 0) and every message type it uses.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Schema {
    /// Message definitions; `defs[0]` is the schema's own type.
    pub defs: Vec<MessageDef>,
}

/// A decoded value.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// `bool`.
    Bool(bool),
    /// Signed integers.
    Int(i64),
    /// Unsigned integers.
    UInt(u64),
    /// `float32`, `float64`.
    Float(f64),
    /// `string`, `wstring`.
    Str(String),
    /// Arrays and sequences of `uint8`, `int8`, `byte`, `char`, `bool`.
    Bytes(Vec<u8>),
    /// Arrays and sequences of `float32`, `float64`.
    Floats(Vec<f64>),
    /// Arrays and sequences of anything else.
    List(Vec<Value>),
    /// A message: its fields' values in definition order.
    Message(Vec<Value>),
}

/// Normalises `pkg/msg/Type` to `pkg/Type`.
fn normalise(name: &str) -> String {
    let parts: Vec<&str> = name.split('/').collect();
    match parts.as_slice() {
        [pkg, "msg", ty] => format!("{pkg}/{ty}"),
        _ => name.to_string(),
    }
}

fn package_of(name: &str) -> &str {
    name.split('/').next().unwrap_or("")
}

/// Field lines of one definition before type resolution.
struct RawDef {
    name: String,
    fields: Vec<(String, String)>,
}

impl Schema {
    /// Parses the definition text of message type `name` (e.g. `sensor_msgs/msg/JointState`).
    ///
    /// # Errors
    /// A message naming the line or type that could not be understood, a type used but not
    /// defined, a recursive definition or one nested deeper than [`MAX_DEPTH`].
    pub fn parse(name: &str, text: &str) -> Result<Schema, String> {
        // sections: the root, then one per `MSG: pkg/Type`
        let mut raws = vec![RawDef { name: normalise(name), fields: Vec::new() }];
        for line in text.lines() {
            let line = line.trim();
            if line.len() >= 3 && line.bytes().all(|b| b == b'=') {
                continue;
            }
            if let Some(msg) = line.strip_prefix("MSG:") {
                raws.push(RawDef { name: normalise(msg.trim()), fields: Vec::new() });
                continue;
            }
            let line = line.split('#').next().unwrap_or("").trim();
            if line.is_empty() {
                continue;
            }
            let mut tokens = line.split_whitespace();
            let (Some(ty), Some(field)) = (tokens.next(), tokens.next()) else {
                return Err(format!("cannot read the definition line '{line}' of {}", raws.last().map_or("", |r| &r.name)));
            };
            // constants: `type NAME=value` or `type NAME = value`
            if field.contains('=') || tokens.next().is_some_and(|t| t.starts_with('=')) {
                continue;
            }
            raws.last_mut().expect("root section").fields.push((ty.to_string(), field.to_string()));
        }
        // builtin_interfaces without a definition in the text
        for builtin in ["builtin_interfaces/Time", "builtin_interfaces/Duration"] {
            if !raws.iter().any(|r| r.name == builtin) {
                raws.push(RawDef { name: builtin.into(), fields: vec![("int32".into(), "sec".into()), ("uint32".into(), "nanosec".into())] });
            }
        }
        // resolve field types
        let index: HashMap<String, usize> = raws.iter().enumerate().rev().map(|(i, r)| (r.name.clone(), i)).collect();
        let mut defs = Vec::with_capacity(raws.len());
        for raw in &raws {
            let mut fields = Vec::with_capacity(raw.fields.len());
            for (ty, fname) in &raw.fields {
                let (base, arity) = match ty.find('[') {
                    Some(i) => {
                        let inner = ty[i + 1..].strip_suffix(']').ok_or_else(|| format!("malformed array type '{ty}' in {}", raw.name))?;
                        let arity = if inner.is_empty() || inner.starts_with("<=") {
                            Arity::Sequence
                        } else {
                            Arity::Fixed(inner.parse().map_err(|_| format!("malformed array size in '{ty}' in {}", raw.name))?)
                        };
                        (&ty[..i], arity)
                    }
                    None => (ty.as_str(), Arity::Single),
                };
                let elem = match (Primitive::parse(base), base) {
                    (Some(p), _) => ElemType::Primitive(p),
                    (None, "time") => ElemType::Message(index["builtin_interfaces/Time"]),
                    (None, "duration") => ElemType::Message(index["builtin_interfaces/Duration"]),
                    (None, other) => {
                        let full = if other.contains('/') {
                            normalise(other)
                        } else if other == "Header" {
                            "std_msgs/Header".to_string()
                        } else {
                            format!("{}/{other}", package_of(&raw.name))
                        };
                        ElemType::Message(*index.get(&full).ok_or_else(|| format!("type '{other}' of field '{fname}' in {} is not defined in the schema", raw.name))?)
                    }
                };
                fields.push(Field { name: fname.clone(), elem, arity });
            }
            defs.push(MessageDef { name: raw.name.clone(), fields, min_size: 0 });
        }
        let mut schema = Schema { defs };
        // sizes, depth first; refuses cycles and deep nesting
        let mut state = vec![0u8; schema.defs.len()];
        schema.size_of(0, 0, &mut state)?;
        Ok(schema)
    }

    /// Computes `min_size` of definition `i` and the types it uses.
    fn size_of(&mut self, i: usize, depth: usize, state: &mut [u8]) -> Result<usize, String> {
        if depth > MAX_DEPTH {
            return Err(format!("message types nested deeper than {MAX_DEPTH} levels at {}", self.defs[i].name));
        }
        match state[i] {
            2 => return Ok(self.defs[i].min_size),
            1 => return Err(format!("recursive message definition: {} contains itself", self.defs[i].name)),
            _ => {}
        }
        state[i] = 1;
        let mut total = 0usize;
        for f in 0..self.defs[i].fields.len() {
            let field = self.defs[i].fields[f].clone();
            let elem = match field.elem {
                ElemType::Primitive(p) => p.size(),
                ElemType::Message(m) => self.size_of(m, depth + 1, state)?,
            };
            total = total.saturating_add(match field.arity {
                Arity::Single => elem,
                Arity::Fixed(n) => elem.saturating_mul(n),
                Arity::Sequence => 4,
            });
        }
        state[i] = 2;
        self.defs[i].min_size = total.max(1);
        Ok(self.defs[i].min_size)
    }

    /// The root type's name (`pkg/Type`).
    pub fn name(&self) -> &str {
        &self.defs[0].name
    }

    /// The field indices of a dotted path from the root (`reference.positions`), and the field
    /// at its end. Only single (non-array) messages can be gone through.
    pub fn path(&self, dotted: &str) -> Option<(Vec<usize>, &Field)> {
        let mut def = 0;
        let mut out = Vec::new();
        let parts: Vec<&str> = dotted.split('.').collect();
        for (k, part) in parts.iter().enumerate() {
            let i = self.defs[def].fields.iter().position(|f| f.name == *part)?;
            let field = &self.defs[def].fields[i];
            out.push(i);
            if k + 1 == parts.len() {
                return Some((out, field));
            }
            match (field.elem, field.arity) {
                (ElemType::Message(m), Arity::Single) => def = m,
                _ => return None,
            }
        }
        None
    }

    /// The message definition a single-message field at `path` has.
    pub fn message_at(&self, dotted: &str) -> Option<&MessageDef> {
        match self.path(dotted)?.1 {
            Field { elem: ElemType::Message(m), arity: Arity::Single, .. } => Some(&self.defs[*m]),
            _ => None,
        }
    }

    /// Decodes a CDR message (with its encapsulation header) of the root type.
    ///
    /// # Errors
    /// [`CdrError`] naming the field where the data ended or was invalid.
    pub fn decode(&self, data: &[u8]) -> Result<Value, CdrError> {
        let little = encapsulation(data)?;
        let mut r = CdrReader::new(&data[4..], little);
        self.decode_message(0, &mut r)
    }

    fn decode_message(&self, def: usize, r: &mut CdrReader<'_>) -> Result<Value, CdrError> {
        let d = &self.defs[def];
        let mut values = Vec::with_capacity(d.fields.len());
        for f in &d.fields {
            let n = match f.arity {
                Arity::Single => {
                    values.push(self.decode_elem(f, r)?);
                    continue;
                }
                Arity::Fixed(n) => n,
                Arity::Sequence => r.u32(&f.name)? as usize,
            };
            // a count is trusted only when its smallest encoding fits in what remains
            let elem_min = match f.elem {
                ElemType::Primitive(p) => p.size(),
                ElemType::Message(m) => self.defs[m].min_size,
            };
            if n.saturating_mul(elem_min.max(1)) > r.remaining() {
                return Err(CdrError(format!("field '{}' claims {n} elements but the message is shorter", f.name)));
            }
            values.push(match f.elem {
                ElemType::Primitive(Primitive::F64) => Value::Floats((0..n).map(|_| r.f64(&f.name)).collect::<Result<_, _>>()?),
                ElemType::Primitive(Primitive::F32) => {
                    Value::Floats((0..n).map(|_| read_n::<4>(r, &f.name).map(|b| f64::from(f32::from_bits(word32(b, r.little))))).collect::<Result<_, _>>()?)
                }
                ElemType::Primitive(Primitive::U8 | Primitive::I8 | Primitive::Bool) => Value::Bytes(r.take(n, 1, &f.name)?.to_vec()),
                _ => Value::List((0..n).map(|_| self.decode_elem(f, r)).collect::<Result<_, _>>()?),
            });
        }
        Ok(Value::Message(values))
    }

    fn decode_elem(&self, f: &Field, r: &mut CdrReader<'_>) -> Result<Value, CdrError> {
        let name = f.name.as_str();
        let little = r.little;
        Ok(match f.elem {
            ElemType::Message(m) => self.decode_message(m, r)?,
            ElemType::Primitive(p) => match p {
                Primitive::Bool => Value::Bool(r.take(1, 1, name)?[0] != 0),
                Primitive::U8 => Value::UInt(u64::from(r.take(1, 1, name)?[0])),
                Primitive::I8 => Value::Int(i64::from(r.take(1, 1, name)?[0] as i8)),
                Primitive::I16 => Value::Int(i64::from(word16(read_n::<2>(r, name)?, little) as i16)),
                Primitive::U16 => Value::UInt(u64::from(word16(read_n::<2>(r, name)?, little))),
                Primitive::I32 => Value::Int(i64::from(word32(read_n::<4>(r, name)?, little) as i32)),
                Primitive::U32 => Value::UInt(u64::from(word32(read_n::<4>(r, name)?, little))),
                Primitive::I64 => Value::Int(word64(read_n::<8>(r, name)?, little) as i64),
                Primitive::U64 => Value::UInt(word64(read_n::<8>(r, name)?, little)),
                Primitive::F32 => Value::Float(f64::from(f32::from_bits(word32(read_n::<4>(r, name)?, little)))),
                Primitive::F64 => Value::Float(r.f64(name)?),
                Primitive::String => Value::Str(r.string(name)?),
                Primitive::WString => {
                    let n = r.count(name, 4)?;
                    let mut s = String::new();
                    for _ in 0..n {
                        let c = word32(read_n::<4>(r, name)?, little);
                        s.push(char::from_u32(c).unwrap_or(char::REPLACEMENT_CHARACTER));
                    }
                    Value::Str(s.trim_end_matches('\0').to_string())
                }
            },
        })
    }
}

fn read_n<const N: usize>(r: &mut CdrReader<'_>, field: &str) -> Result<[u8; N], CdrError> {
    let s = r.take(N, N, field)?;
    let mut b = [0u8; N];
    b.copy_from_slice(s);
    Ok(b)
}

fn word16(b: [u8; 2], little: bool) -> u16 {
    if little {
        u16::from_le_bytes(b)
    } else {
        u16::from_be_bytes(b)
    }
}

fn word32(b: [u8; 4], little: bool) -> u32 {
    if little {
        u32::from_le_bytes(b)
    } else {
        u32::from_be_bytes(b)
    }
}

fn word64(b: [u8; 8], little: bool) -> u64 {
    if little {
        u64::from_le_bytes(b)
    } else {
        u64::from_be_bytes(b)
    }
}

impl Value {
    /// The value at a path of field indices (from [`Schema::path`]).
    pub fn at(&self, path: &[usize]) -> Option<&Value> {
        let mut v = self;
        for &i in path {
            match v {
                Value::Message(fields) => v = fields.get(i)?,
                _ => return None,
            }
        }
        Some(v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcap::cdr::JointState;
    use crate::mcap::JOINT_STATE_DEFINITION;

    #[test]
    fn joint_state_decoded_from_its_definition_matches_the_hand_decoder() {
        let schema = Schema::parse("sensor_msgs/msg/JointState", JOINT_STATE_DEFINITION).unwrap();
        let msg =
            JointState { sec: 12, nanosec: 34, frame_id: "base".into(), name: vec!["a".into(), "bc".into()], position: vec![1.0, -2.5], velocity: vec![], effort: vec![0.25, 4.0] };
        let v = schema.decode(&msg.encode_cdr()).unwrap();
        let (p, _) = schema.path("header.stamp.nanosec").unwrap();
        assert_eq!(v.at(&p), Some(&Value::UInt(34)));
        let (p, _) = schema.path("name").unwrap();
        assert_eq!(v.at(&p), Some(&Value::List(vec![Value::Str("a".into()), Value::Str("bc".into())])));
        let (p, _) = schema.path("effort").unwrap();
        assert_eq!(v.at(&p), Some(&Value::Floats(vec![0.25, 4.0])));
        let (p, _) = schema.path("velocity").unwrap();
        assert_eq!(v.at(&p), Some(&Value::Floats(vec![])));
    }

    #[test]
    fn recursive_undefined_and_huge_definitions_are_refused() {
        assert!(Schema::parse("a/msg/A", "a/A child\n").unwrap_err().contains("recursive"));
        assert!(Schema::parse("a/msg/A", "B child\n").unwrap_err().contains("not defined"));
        let huge = Schema::parse("a/msg/A", "float64[4000000000] x\n").unwrap();
        assert!(huge.decode(&[0, 1, 0, 0, 0, 0, 0, 0]).is_err());
        let empty_seq = Schema::parse("a/msg/A", "B[] x\n===\nMSG: a/B\n").unwrap();
        assert!(empty_seq.decode(&[0, 1, 0, 0, 0xff, 0xff, 0xff, 0xff]).is_err());
    }
}
