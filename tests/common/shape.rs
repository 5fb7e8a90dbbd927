//! The shape of a serde value — its types, struct and field names, variants and the shape of the
//! first element of each sequence, without the values — as one string. A fingerprint of it tells when
//! an encoding whose bytes carry no field names (postcard: keyframes, replay files) changes, so that
//! the layout number that guards old files (`SNAPSHOT_LAYOUT`) is bumped with it. Byte blobs are the
//! exception: they give their length (a GPU buffer's layout is the size of its records).

use serde::ser::{self, Serialize};

/// The shape of `value` (see the module docs).
pub fn shape_of<T: Serialize + ?Sized>(value: &T) -> String {
    value.serialize(Shape).unwrap_or_else(|e| format!("<{e}>"))
}

/// FNV-1a 64 of a string (a stable fingerprint to write into a test).
pub fn fnv1a(s: &str) -> u64 {
    s.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

#[derive(Debug)]
pub struct ShapeError(String);

impl std::fmt::Display for ShapeError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ShapeError {}

impl ser::Error for ShapeError {
    fn custom<T: std::fmt::Display>(msg: T) -> Self {
        ShapeError(msg.to_string())
    }
}

struct Shape;

/// A compound being written: its opening, the parts so far, and whether its elements are a set
/// (sequences: their length is a value, not a shape, so each distinct element shape counts once —
/// an object list gives its box and its sphere, a `Vec<f32>` one `f32`).
pub struct Parts {
    open: String,
    close: &'static str,
    parts: Vec<String>,
    distinct: bool,
    count: usize,
}

impl Parts {
    fn new(open: String, close: &'static str, distinct: bool) -> Parts {
        Parts { open, close, parts: Vec::new(), distinct, count: 0 }
    }

    fn push(&mut self, part: String) {
        self.count += 1;
        if !(self.distinct && self.parts.contains(&part)) {
            self.parts.push(part);
        }
    }

    /// A byte blob (`Vec<u8>`: the GPU's state buffers, byte for byte) gives its length, since its
    /// layout lives in the size of the records it holds.
    fn done(self) -> String {
        if self.distinct && self.parts == ["u8"] {
            return format!("[u8;{}]", self.count);
        }
        format!("{}{}{}", self.open, self.parts.join(","), self.close)
    }
}

macro_rules! prim {
    ($($f:ident: $t:ty),*) => {
        $(fn $f(self, _: $t) -> Result<String, ShapeError> {
            Ok(stringify!($t).to_string())
        })*
    };
}

impl ser::Serializer for Shape {
    type Ok = String;
    type Error = ShapeError;
    type SerializeSeq = Parts;
    type SerializeTuple = Parts;
    type SerializeTupleStruct = Parts;
    type SerializeTupleVariant = Parts;
    type SerializeMap = Parts;
    type SerializeStruct = Parts;
    type SerializeStructVariant = Parts;

    prim!(serialize_bool: bool, serialize_i8: i8, serialize_i16: i16, serialize_i32: i32, serialize_i64: i64,
          serialize_u8: u8, serialize_u16: u16, serialize_u32: u32, serialize_u64: u64, serialize_f32: f32,
          serialize_f64: f64, serialize_char: char, serialize_str: &str, serialize_bytes: &[u8]);

    fn serialize_none(self) -> Result<String, ShapeError> {
        Ok("None".into())
    }
    fn serialize_some<T: Serialize + ?Sized>(self, v: &T) -> Result<String, ShapeError> {
        Ok(format!("Some({})", v.serialize(Shape)?))
    }
    fn serialize_unit(self) -> Result<String, ShapeError> {
        Ok("()".into())
    }
    fn serialize_unit_struct(self, name: &'static str) -> Result<String, ShapeError> {
        Ok(name.into())
    }
    fn serialize_unit_variant(self, name: &'static str, _: u32, variant: &'static str) -> Result<String, ShapeError> {
        Ok(format!("{name}::{variant}"))
    }
    fn serialize_newtype_struct<T: Serialize + ?Sized>(self, name: &'static str, v: &T) -> Result<String, ShapeError> {
        Ok(format!("{name}({})", v.serialize(Shape)?))
    }
    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        name: &'static str,
        _: u32,
        variant: &'static str,
        v: &T,
    ) -> Result<String, ShapeError> {
        Ok(format!("{name}::{variant}({})", v.serialize(Shape)?))
    }
    fn serialize_seq(self, _: Option<usize>) -> Result<Parts, ShapeError> {
        Ok(Parts::new("[".into(), "]", true))
    }
    fn serialize_tuple(self, _: usize) -> Result<Parts, ShapeError> {
        Ok(Parts::new("(".into(), ")", false))
    }
    fn serialize_tuple_struct(self, name: &'static str, _: usize) -> Result<Parts, ShapeError> {
        Ok(Parts::new(format!("{name}("), ")", false))
    }
    fn serialize_tuple_variant(
        self,
        name: &'static str,
        _: u32,
        variant: &'static str,
        _: usize,
    ) -> Result<Parts, ShapeError> {
        Ok(Parts::new(format!("{name}::{variant}("), ")", false))
    }
    fn serialize_map(self, _: Option<usize>) -> Result<Parts, ShapeError> {
        Ok(Parts::new("{".into(), "}", true))
    }
    fn serialize_struct(self, name: &'static str, _: usize) -> Result<Parts, ShapeError> {
        Ok(Parts::new(format!("{name}{{"), "}", false))
    }
    fn serialize_struct_variant(
        self,
        name: &'static str,
        _: u32,
        variant: &'static str,
        _: usize,
    ) -> Result<Parts, ShapeError> {
        Ok(Parts::new(format!("{name}::{variant}{{"), "}", false))
    }
}

/// The element-wise compounds: each element's shape is one part.
macro_rules! elements {
    ($($trait:ident :: $method:ident),*) => {
        $(impl ser::$trait for Parts {
            type Ok = String;
            type Error = ShapeError;
            fn $method<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), ShapeError> {
                self.push(v.serialize(Shape)?);
                Ok(())
            }
            fn end(self) -> Result<String, ShapeError> {
                Ok(self.done())
            }
        })*
    };
}

elements!(
    SerializeSeq::serialize_element,
    SerializeTuple::serialize_element,
    SerializeTupleStruct::serialize_field,
    SerializeTupleVariant::serialize_field
);

/// The named-field compounds: each field is `name:shape`.
macro_rules! fields {
    ($($trait:ident),*) => {
        $(impl ser::$trait for Parts {
            type Ok = String;
            type Error = ShapeError;
            fn serialize_field<T: Serialize + ?Sized>(&mut self, key: &'static str, v: &T) -> Result<(), ShapeError> {
                self.push(format!("{key}:{}", v.serialize(Shape)?));
                Ok(())
            }
            fn end(self) -> Result<String, ShapeError> {
                Ok(self.done())
            }
        })*
    };
}

fields!(SerializeStruct, SerializeStructVariant);

impl ser::SerializeMap for Parts {
    type Ok = String;
    type Error = ShapeError;
    fn serialize_key<T: Serialize + ?Sized>(&mut self, k: &T) -> Result<(), ShapeError> {
        // the key's shape waits in `open`'s tail until its value comes
        self.open.push_str(&format!("\u{0}{}:", k.serialize(Shape)?));
        Ok(())
    }
    fn serialize_value<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), ShapeError> {
        let v = v.serialize(Shape)?;
        let (open, key) =
            self.open.split_once('\u{0}').map(|(o, k)| (o.to_string(), k.to_string())).unwrap_or_default();
        self.open = open;
        self.push(format!("{key}{v}"));
        Ok(())
    }
    fn end(self) -> Result<String, ShapeError> {
        Ok(self.done())
    }
}
