//! Derives of `harvest-ipc`. The traits they implement, and what each promises, are documented
//! where they are declared: `harvest_ipc::any_bit_pattern::AnyBitPattern` (the memory contract of
//! every payload), `harvest_ipc::wire_code::WireEnum` (an enum carried as a `u8` code),
//! `harvest_ipc::schema::Describe` (how the codec writes a type, for the recorded schema) and
//! `harvest_ipc::payload::Payload` (a message type, declared once).
//!
//! The generated code names the traits through `::harvest_ipc`, so it works in any crate that
//! depends on `harvest-ipc` (and in `harvest-ipc` itself, which declares
//! `extern crate self as harvest_ipc`).

#![forbid(unsafe_code)]
#![cfg_attr(not(test), deny(clippy::unwrap_used, clippy::expect_used))]
#![deny(missing_docs)]

use proc_macro::TokenStream;
use proc_macro2::TokenStream as TokenStream2;
use quote::quote;
use syn::{
    Attribute, Data, DeriveInput, Error, Expr, ExprLit, Fields, Lit, LitStr, Meta, Type,
    parse_macro_input, parse_quote,
};

/// Implements `harvest_ipc::any_bit_pattern::AnyBitPattern` for a struct after checking, at
/// compile time, that:
///
/// - the struct is `#[repr(C)]` (or `#[repr(transparent)]`) and not packed;
/// - every field's type implements `AnyBitPattern` (integers, floats, arrays of those and
///   structs deriving it; `bool`, `char`, enums and references do not);
/// - the struct has no padding: its size equals the sum of its fields' sizes.
///
/// For a generic struct the padding check runs for each concrete instantiation that a
/// non-generic `AnyBitPattern` type contains, or that the transport uses.
#[proc_macro_derive(AnyBitPattern)]
pub fn derive_any_bit_pattern(input: TokenStream) -> TokenStream {
    let input = parse_macro_input!(input as DeriveInput);
    any_bit_pattern(&input)
        .unwrap_or_else(Error::into_compile_error)
        .into()
}

/// Implements `harvest_ipc::wire_code::WireEnum` for a `#[repr(u8)]` enum of unit variants:
/// its code is the discriminant, its name the enum's name. Also implements
/// `harvest_ipc::schema::Describe`: the enum's codes with the variants' names and docs.
#[proc_macro_derive(WireEnum)]
pub fn derive_wire_enum(input: TokenStream) -> TokenStream {
    let input = parse_macro_input!(input as DeriveInput);
    wire_enum(&input)
        .unwrap_or_else(Error::into_compile_error)
        .into()
}

/// Implements `harvest_ipc::schema::Describe` for a struct with named fields: its fields in
/// declaration order, each with its name, the first paragraph of its doc comment and its type's
/// shape (every field type must implement `Describe`). The shape must be what the codec writes:
/// serde writes the fields in declaration order, which is what this describes. Two field
/// attributes describe a type whose codec is written by hand (`#[payload(custom_codec)]`):
///
/// - `#[schema(skip)]`: the codec leaves the field out;
/// - `#[schema(count = "meta.point_count")]` on an array field: the codec writes only as many
///   items as the earlier field at that dotted path says, with no count of its own.
#[proc_macro_derive(Describe, attributes(schema))]
pub fn derive_describe(input: TokenStream) -> TokenStream {
    let input = parse_macro_input!(input as DeriveInput);
    describe(&input)
        .unwrap_or_else(Error::into_compile_error)
        .into()
}

/// Implements `harvest_ipc::payload::Payload` and `harvest_ipc::schema::Describe` for a message
/// type, declared once: `TYPE_NAME` and `VERSION` come from iceoryx2's
/// `#[type_name("harvest.ArmState.v2")]` (which must end in `.v<VERSION>`), the header is the
/// field `header`, the schema is the fields (see `Describe`), and the codec is serde through
/// `harvest_ipc::codec`, or the type's `harvest_ipc::payload::CustomCodec` with
/// `#[payload(custom_codec)]`.
#[proc_macro_derive(Payload, attributes(payload, schema))]
pub fn derive_payload(input: TokenStream) -> TokenStream {
    let input = parse_macro_input!(input as DeriveInput);
    payload(&input)
        .map(|payload| {
            let describe = describe(&input).unwrap_or_else(Error::into_compile_error);
            quote!(#payload #describe)
        })
        .unwrap_or_else(Error::into_compile_error)
        .into()
}

/// The first paragraph of the doc comment in `attrs`, on one line (empty without one).
fn doc_summary(attrs: &[Attribute]) -> String {
    let mut summary = String::new();
    for attr in attrs.iter().filter(|attr| attr.path().is_ident("doc")) {
        let Meta::NameValue(name_value) = &attr.meta else {
            continue;
        };
        let Expr::Lit(ExprLit {
            lit: Lit::Str(text),
            ..
        }) = &name_value.value
        else {
            continue;
        };
        // An empty `///` line is an attribute of its own with an empty value: a paragraph break.
        for line in text.value().split('\n') {
            let line = line.trim();
            if line.is_empty() {
                if !summary.is_empty() {
                    return summary;
                }
                continue;
            }
            if !summary.is_empty() {
                summary.push(' ');
            }
            summary.push_str(line);
        }
    }
    summary
}

/// What `#[schema(..)]` says of a field.
#[derive(Default)]
struct FieldSchema {
    skip: bool,
    count: Option<LitStr>,
}

fn field_schema(attrs: &[Attribute]) -> syn::Result<FieldSchema> {
    let mut schema = FieldSchema::default();
    for attr in attrs.iter().filter(|attr| attr.path().is_ident("schema")) {
        attr.parse_nested_meta(|meta| {
            if meta.path.is_ident("skip") {
                schema.skip = true;
                Ok(())
            } else if meta.path.is_ident("count") {
                schema.count = Some(meta.value()?.parse()?);
                Ok(())
            } else {
                Err(meta.error("expected `skip` or `count = \"field.path\"`"))
            }
        })?;
    }
    Ok(schema)
}

fn describe(input: &DeriveInput) -> syn::Result<TokenStream2> {
    let name = &input.ident;
    let Data::Struct(data) = &input.data else {
        return Err(Error::new_spanned(
            name,
            "`#[derive(Describe)]` applies to structs; an enum is described by \
`#[derive(WireEnum)]`",
        ));
    };
    let Fields::Named(fields) = &data.fields else {
        return Err(Error::new_spanned(
            name,
            "`#[derive(Describe)]` needs named fields: the schema names each one",
        ));
    };
    let krate = quote!(::harvest_ipc::schema);
    let mut generics = input.generics.clone();
    let where_clause = generics.make_where_clause();
    let mut shapes = Vec::new();
    for field in &fields.named {
        let schema = field_schema(&field.attrs)?;
        if schema.skip {
            continue;
        }
        let ty = &field.ty;
        let field_name = field
            .ident
            .as_ref()
            .map(ToString::to_string)
            .unwrap_or_default();
        let doc = doc_summary(&field.attrs);
        let shape = match &schema.count {
            None => {
                where_clause
                    .predicates
                    .push(parse_quote!(#ty: #krate::Describe));
                quote!(<#ty as #krate::Describe>::shape())
            }
            Some(count_field) => {
                let Type::Array(array) = ty else {
                    return Err(Error::new_spanned(
                        ty,
                        "`#[schema(count = ..)]` applies to an array field: its items are \
written up to the count",
                    ));
                };
                let (item, len) = (&array.elem, &array.len);
                where_clause
                    .predicates
                    .push(parse_quote!(#item: #krate::Describe));
                quote!(#krate::Shape::Counted {
                    item: ::std::boxed::Box::new(<#item as #krate::Describe>::shape()),
                    count_field: #count_field,
                    max_len: #len,
                })
            }
        };
        shapes.push(quote! {
            #krate::FieldShape { name: #field_name, doc: #doc, shape: #shape }
        });
    }
    let (impl_generics, ty_generics, where_clause) = generics.split_for_impl();
    let name_text = name.to_string();
    let doc = doc_summary(&input.attrs);
    Ok(quote! {
        impl #impl_generics #krate::Describe for #name #ty_generics #where_clause {
            fn shape() -> #krate::Shape {
                #krate::Shape::Struct(#krate::StructShape {
                    name: #name_text,
                    doc: #doc,
                    fields: ::std::vec![#(#shapes),*],
                })
            }
        }
    })
}

fn payload(input: &DeriveInput) -> syn::Result<TokenStream2> {
    let name = &input.ident;
    let mut type_name = None;
    let mut custom_codec = false;
    for attr in &input.attrs {
        if attr.path().is_ident("type_name") {
            type_name = Some(attr.parse_args::<LitStr>()?);
        } else if attr.path().is_ident("payload") {
            attr.parse_nested_meta(|meta| {
                if meta.path.is_ident("custom_codec") {
                    custom_codec = true;
                    Ok(())
                } else {
                    Err(meta.error("expected `custom_codec`"))
                }
            })?;
        }
    }
    let missing = || {
        Error::new_spanned(
            name,
            format!(
                "`#[derive(Payload)]` takes the name and version from iceoryx2's \
`#[type_name(\"harvest.{name}.v1\")]` on `{name}`: add it"
            ),
        )
    };
    let type_name = type_name.ok_or_else(missing)?;
    let full_name = type_name.value();
    let (base_name, version) = full_name
        .rsplit_once(".v")
        .and_then(|(base, version)| Some((base, version.parse::<u32>().ok()?)))
        .filter(|(base, _)| !base.is_empty())
        .ok_or_else(|| {
            Error::new_spanned(
                &type_name,
                format!(
                    "`#[type_name(\"{full_name}\")]` must be `<TYPE_NAME>.v<VERSION>`, e.g. \
`harvest.{name}.v1`"
                ),
            )
        })?;
    let (impl_generics, ty_generics, where_clause) = input.generics.split_for_impl();
    let krate = quote!(::harvest_ipc);
    let codec = if custom_codec {
        quote! {
            fn encode(
                &self,
                out: &mut ::std::vec::Vec<u8>,
            ) -> ::core::result::Result<(), #krate::codec::CodecError> {
                <Self as #krate::payload::CustomCodec>::encode(self, out)
            }
            fn decode_into(
                bytes: &[u8],
                dst: &mut Self,
            ) -> ::core::result::Result<(), #krate::codec::CodecError> {
                <Self as #krate::payload::CustomCodec>::decode_into(bytes, dst)
            }
            fn to_json(&self) -> #krate::__private::serde_json::Value {
                <Self as #krate::payload::CustomCodec>::to_json(self)
            }
        }
    } else {
        quote! {
            fn encode(
                &self,
                out: &mut ::std::vec::Vec<u8>,
            ) -> ::core::result::Result<(), #krate::codec::CodecError> {
                #krate::codec::encode_into(self, out)
            }
            fn decode_into(
                bytes: &[u8],
                dst: &mut Self,
            ) -> ::core::result::Result<(), #krate::codec::CodecError> {
                *dst = #krate::codec::decode_exact(bytes)?;
                ::core::result::Result::Ok(())
            }
            fn to_json(&self) -> #krate::__private::serde_json::Value {
                #krate::payload::serde_json_of(self)
            }
        }
    };
    Ok(quote! {
        impl #impl_generics #krate::payload::Payload for #name #ty_generics #where_clause {
            const TYPE_NAME: &'static str = #base_name;
            const VERSION: u32 = #version;

            fn header(&self) -> &#krate::header::Header {
                &self.header
            }
            fn header_mut(&mut self) -> &mut #krate::header::Header {
                &mut self.header
            }
            #codec
        }
    })
}

/// The `repr` hints of a type: (`C` or `transparent` present, `packed` present, `u8` present).
fn repr_hints(attrs: &[Attribute]) -> syn::Result<(bool, bool, bool)> {
    let (mut c_like, mut packed, mut u8_repr) = (false, false, false);
    for attr in attrs.iter().filter(|attr| attr.path().is_ident("repr")) {
        attr.parse_nested_meta(|meta| {
            if meta.path.is_ident("C") || meta.path.is_ident("transparent") {
                c_like = true;
            } else if meta.path.is_ident("packed") {
                packed = true;
                if meta.input.peek(syn::token::Paren) {
                    let _content;
                    syn::parenthesized!(_content in meta.input);
                }
            } else if meta.path.is_ident("u8") {
                u8_repr = true;
            } else if meta.input.peek(syn::token::Paren) {
                // `align(N)` and the like: skip the argument; the padding check judges the result.
                let _content;
                syn::parenthesized!(_content in meta.input);
            }
            Ok(())
        })?;
    }
    Ok((c_like, packed, u8_repr))
}

fn any_bit_pattern(input: &DeriveInput) -> syn::Result<TokenStream2> {
    let name = &input.ident;
    let Data::Struct(data) = &input.data else {
        return Err(Error::new_spanned(
            name,
            "`#[derive(AnyBitPattern)]` applies to structs only: an enum has invalid bit patterns \
(carry it as a `WireCode`), a union has no checkable layout",
        ));
    };
    let (c_like, packed, _) = repr_hints(&input.attrs)?;
    if !c_like {
        return Err(Error::new_spanned(
            name,
            format!(
                "`#[derive(AnyBitPattern)]` requires `#[repr(C)]` on `{name}`: the default Rust \
layout may reorder fields and is not a layout another process can rely on"
            ),
        ));
    }
    if packed {
        return Err(Error::new_spanned(
            name,
            format!(
                "`#[derive(AnyBitPattern)]` rejects `#[repr(packed)]` on `{name}`: its fields \
may be unaligned; add explicit `_reserved` fields instead"
            ),
        ));
    }

    let field_types: Vec<&Type> = match &data.fields {
        Fields::Named(fields) => fields.named.iter().map(|field| &field.ty).collect(),
        Fields::Unnamed(fields) => fields.unnamed.iter().map(|field| &field.ty).collect(),
        Fields::Unit => Vec::new(),
    };

    let krate = quote!(::harvest_ipc::any_bit_pattern);
    let mut generics = input.generics.clone();
    let where_clause = generics.make_where_clause();
    for ty in &field_types {
        where_clause
            .predicates
            .push(parse_quote!(#ty: #krate::AnyBitPattern));
    }
    let (impl_generics, ty_generics, where_clause) = generics.split_for_impl();

    let padding_message = format!(
        "`{name}` has padding bytes (its size is not the sum of its fields' sizes): padding is \
not a valid value of any field; add explicit `_reserved` fields where the compiler pads"
    );
    // Non-generic structs are checked where they are declared; generic ones when a concrete
    // instantiation is used (by a containing struct's check or by the transport).
    let eager_check = if input.generics.params.is_empty() {
        quote! {
            const _: () = <#name as #krate::AnyBitPattern>::LAYOUT_CHECK;
        }
    } else {
        TokenStream2::new()
    };

    Ok(quote! {
        // SAFETY: checked by the derive: `#[repr(C)]` (or transparent) and not packed, every
        // field is `AnyBitPattern` (required by the where clause), and `LAYOUT_CHECK` proves at
        // compile time that no padding byte lies between or after the fields.
        unsafe impl #impl_generics #krate::AnyBitPattern for #name #ty_generics #where_clause {
            const LAYOUT_CHECK: () = {
                #( let () = <#field_types as #krate::AnyBitPattern>::LAYOUT_CHECK; )*
                assert!(
                    ::core::mem::size_of::<Self>()
                        == 0usize #( + ::core::mem::size_of::<#field_types>() )*,
                    #padding_message
                );
            };
        }
        #eager_check
    })
}

fn wire_enum(input: &DeriveInput) -> syn::Result<TokenStream2> {
    let name = &input.ident;
    let Data::Enum(data) = &input.data else {
        return Err(Error::new_spanned(
            name,
            "`#[derive(WireEnum)]` applies to enums only",
        ));
    };
    if !input.generics.params.is_empty() {
        return Err(Error::new_spanned(
            &input.generics,
            "`#[derive(WireEnum)]` does not support generic enums",
        ));
    }
    let (_, _, u8_repr) = repr_hints(&input.attrs)?;
    if !u8_repr {
        return Err(Error::new_spanned(
            name,
            format!(
                "`#[derive(WireEnum)]` requires `#[repr(u8)]` on `{name}`: its codes are bytes"
            ),
        ));
    }
    let mut variants = Vec::new();
    let mut variant_shapes = Vec::new();
    let schema = quote!(::harvest_ipc::schema);
    for variant in &data.variants {
        if !matches!(variant.fields, Fields::Unit) {
            return Err(Error::new_spanned(
                &variant.ident,
                "`#[derive(WireEnum)]` requires unit variants: a code carries no data",
            ));
        }
        variants.push(&variant.ident);
        let ident = &variant.ident;
        let variant_name = ident.to_string();
        let doc = doc_summary(&variant.attrs);
        variant_shapes.push(quote! {
            #schema::VariantShape { code: Self::#ident as u8, name: #variant_name, doc: #doc }
        });
    }
    let enum_doc = doc_summary(&input.attrs);
    let name_text = name.to_string();
    let krate = quote!(::harvest_ipc::wire_code);
    Ok(quote! {
        impl #krate::WireEnum for #name {
            const NAME: &'static str = #name_text;
            const ALL: &'static [Self] = &[#(Self::#variants),*];

            fn code(self) -> u8 {
                self as u8
            }

            fn from_code(code: u8) -> ::core::option::Option<Self> {
                #(
                    if code == Self::#variants as u8 {
                        return ::core::option::Option::Some(Self::#variants);
                    }
                )*
                ::core::option::Option::None
            }
        }

        impl #schema::Describe for #name {
            fn shape() -> #schema::Shape {
                #schema::Shape::Code(#schema::EnumShape {
                    name: #name_text,
                    doc: #enum_doc,
                    variants: ::std::vec![#(#variant_shapes),*],
                })
            }
        }
    })
}
