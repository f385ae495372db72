//! What a ROS 2 message type is made of, as data: its fields and constants. From one
//! description come the `.msg` definition text a bag's schema carries
//! ([`MessageType::definition`]) and the RIHS01 type hash that rmw and rosbag2 compare
//! ([`MessageType::type_hash`]).

/// A primitive or nested element type.
#[derive(Debug, Clone, Copy)]
pub enum BaseType {
    Bool,
    Byte,
    Char,
    Int8,
    Uint8,
    Int16,
    Uint16,
    Int32,
    Uint32,
    Int64,
    Uint64,
    Float32,
    Float64,
    /// `string`, or `string<=N` when bounded.
    String {
        bound: Option<u32>,
    },
    /// Another message type.
    Nested(&'static MessageType),
}

/// Single value, fixed array, bounded or unbounded sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Collection {
    Single,
    /// `T[N]`.
    Array(u32),
    /// `T[<=N]`.
    BoundedSequence(u32),
    /// `T[]`.
    Sequence,
}

/// One field of a message.
#[derive(Debug, Clone, Copy)]
pub struct Field {
    pub name: &'static str,
    pub base: BaseType,
    pub collection: Collection,
    /// Default value as written in the `.msg` file (not part of the type hash).
    pub default: Option<&'static str>,
}

/// A constant of a message (part of the definition text, not of the type hash).
#[derive(Debug, Clone, Copy)]
pub struct Constant {
    pub name: &'static str,
    pub base: BaseType,
    pub value: &'static str,
}

/// A message type: `package/msg/Name`, its constants and fields in wire order.
#[derive(Debug)]
pub struct MessageType {
    /// Full name, e.g. `sensor_msgs/msg/Image`.
    pub name: &'static str,
    pub constants: &'static [Constant],
    pub fields: &'static [Field],
}

impl Field {
    /// A single field of a primitive or nested type.
    pub const fn new(name: &'static str, base: BaseType) -> Self {
        Self {
            name,
            base,
            collection: Collection::Single,
            default: None,
        }
    }

    /// An unbounded sequence `T[]`.
    pub const fn sequence(name: &'static str, base: BaseType) -> Self {
        Self {
            name,
            base,
            collection: Collection::Sequence,
            default: None,
        }
    }

    /// A fixed array `T[N]`.
    pub const fn array(name: &'static str, base: BaseType, len: u32) -> Self {
        Self {
            name,
            base,
            collection: Collection::Array(len),
            default: None,
        }
    }

    /// With a default value.
    pub const fn with_default(mut self, default: &'static str) -> Self {
        self.default = Some(default);
        self
    }
}

/// `string` (unbounded).
pub const STRING: BaseType = BaseType::String { bound: None };

impl BaseType {
    /// The type as written in a `.msg` file (nested types as `package/Name`).
    pub fn msg_name(&self) -> String {
        match self {
            Self::Bool => "bool".into(),
            Self::Byte => "byte".into(),
            Self::Char => "char".into(),
            Self::Int8 => "int8".into(),
            Self::Uint8 => "uint8".into(),
            Self::Int16 => "int16".into(),
            Self::Uint16 => "uint16".into(),
            Self::Int32 => "int32".into(),
            Self::Uint32 => "uint32".into(),
            Self::Int64 => "int64".into(),
            Self::Uint64 => "uint64".into(),
            Self::Float32 => "float32".into(),
            Self::Float64 => "float64".into(),
            Self::String { bound: None } => "string".into(),
            Self::String { bound: Some(n) } => format!("string<={n}"),
            Self::Nested(nested) => nested.short_name(),
        }
    }

    /// The `type_description_interfaces/msg/FieldType` id of a single value of this type.
    fn type_id(&self) -> u8 {
        match self {
            Self::Nested(_) => 1,
            Self::Int8 => 2,
            Self::Uint8 => 3,
            Self::Int16 => 4,
            Self::Uint16 => 5,
            Self::Int32 => 6,
            Self::Uint32 => 7,
            Self::Int64 => 8,
            Self::Uint64 => 9,
            Self::Float32 => 10,
            Self::Float64 => 11,
            Self::Char => 13,
            Self::Bool => 15,
            Self::Byte => 16,
            Self::String { bound: None } => 17,
            Self::String { bound: Some(_) } => 21,
        }
    }
}

impl Field {
    /// The field's line in a `.msg` file.
    pub fn msg_line(&self) -> String {
        let suffix = match self.collection {
            Collection::Single => String::new(),
            Collection::Array(n) => format!("[{n}]"),
            Collection::BoundedSequence(n) => format!("[<={n}]"),
            Collection::Sequence => "[]".into(),
        };
        let mut line = format!("{}{suffix} {}", self.base.msg_name(), self.name);
        if let Some(default) = self.default {
            line.push(' ');
            line.push_str(default);
        }
        line
    }
}

impl MessageType {
    /// `sensor_msgs/msg/Image` -> `sensor_msgs/Image`, the form `.msg` files and bag schemas
    /// use to name a type.
    pub fn short_name(&self) -> String {
        self.name.replacen("/msg/", "/", 1)
    }

    /// This type's own `.msg` text: constants, then fields, one a line.
    pub fn own_definition(&self) -> String {
        let mut text = String::new();
        for constant in self.constants {
            text.push_str(&format!(
                "{} {}={}\n",
                constant.base.msg_name(),
                constant.name,
                constant.value
            ));
        }
        for field in self.fields {
            text.push_str(&field.msg_line());
            text.push('\n');
        }
        text
    }

    /// Every type this one uses, directly or not, each once, in order of first use.
    pub fn dependencies(&self) -> Vec<&'static MessageType> {
        fn visit(ty: &MessageType, found: &mut Vec<&'static MessageType>) {
            for field in ty.fields {
                if let BaseType::Nested(nested) = field.base
                    && !found.iter().any(|known| known.name == nested.name)
                {
                    found.push(nested);
                    visit(nested, found);
                }
            }
        }
        let mut found = Vec::new();
        visit(self, &mut found);
        found.retain(|ty| ty.name != self.name);
        found
    }

    /// The full definition as rosbag2 stores it in a schema (encoding `ros2msg`): this type's
    /// text, then each dependency after a line of 80 `=` and `MSG: package/Name`.
    pub fn definition(&self) -> String {
        let mut text = self.own_definition();
        for dependency in self.dependencies() {
            text.push_str(&"=".repeat(80));
            text.push_str("\nMSG: ");
            text.push_str(&dependency.short_name());
            text.push('\n');
            text.push_str(&dependency.own_definition());
        }
        text
    }

    /// The type's hashable description as JSON, exactly as `rosidl_generator_type_description`
    /// writes it before hashing (`json.dumps` with `", "` and `": "` separators): this type's
    /// fields, then every referenced type sorted by name; constants and defaults left out.
    pub fn hashable_description(&self) -> String {
        let mut referenced = self.dependencies();
        referenced.sort_by_key(|ty| ty.name);
        let mut json = String::from("{\"type_description\": ");
        self.push_description(&mut json);
        json.push_str(", \"referenced_type_descriptions\": [");
        for (index, ty) in referenced.iter().enumerate() {
            if index > 0 {
                json.push_str(", ");
            }
            ty.push_description(&mut json);
        }
        json.push_str("]}");
        json
    }

    fn push_description(&self, json: &mut String) {
        json.push_str(&format!(
            "{{\"type_name\": \"{}\", \"fields\": [",
            self.name
        ));
        // An empty message gets the placeholder member the IDL needs.
        const PLACEHOLDER: Field =
            Field::new("structure_needs_at_least_one_member", BaseType::Uint8);
        let fields: &[Field] = if self.fields.is_empty() {
            std::slice::from_ref(&PLACEHOLDER)
        } else {
            self.fields
        };
        for (index, field) in fields.iter().enumerate() {
            if index > 0 {
                json.push_str(", ");
            }
            let (offset, capacity) = match field.collection {
                Collection::Single => (0, 0),
                Collection::Array(n) => (48, n),
                Collection::BoundedSequence(n) => (96, n),
                Collection::Sequence => (144, 0),
            };
            let string_capacity = match field.base {
                BaseType::String { bound: Some(n) } => n,
                _ => 0,
            };
            let nested = match field.base {
                BaseType::Nested(nested) => nested.name,
                _ => "",
            };
            json.push_str(&format!(
                "{{\"name\": \"{}\", \"type\": {{\"type_id\": {}, \"capacity\": {capacity}, \"string_capacity\": {string_capacity}, \"nested_type_name\": \"{nested}\"}}}}",
                field.name,
                u32::from(field.base.type_id()) + offset,
            ));
        }
        json.push_str("]}");
    }

    /// The RIHS01 type hash (`RIHS01_` and the SHA-256 of [`Self::hashable_description`] in
    /// lower-case hex), as `ros2 topic info -v`, rmw_zenoh key expressions and rosbag2's
    /// `type_description_hash` show it.
    pub fn type_hash(&self) -> String {
        use sha2::Digest;
        let digest = sha2::Sha256::digest(self.hashable_description().as_bytes());
        let mut hash = String::from("RIHS01_");
        for byte in digest {
            hash.push_str(&format!("{byte:02x}"));
        }
        hash
    }

    /// The DDS type name rmw implementations use on the wire, e.g.
    /// `sensor_msgs::msg::dds_::Image_`.
    pub fn dds_name(&self) -> String {
        let mut parts: Vec<&str> = self.name.split('/').collect();
        let last = parts.pop().unwrap_or_default();
        format!("{}::dds_::{last}_", parts.join("::"))
    }
}
