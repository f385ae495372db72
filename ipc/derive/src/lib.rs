//! Derives of `harvest-ipc`. The traits they implement, and what each promises, are documented
//! where they are declared: `harvest_ipc::any_bit_pattern::AnyBitPattern` (the memory contract of
//! every payload) and `harvest_ipc::wire_code::WireEnum` (an enum carried as a `u8` code).
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
use syn::{Attribute, Data, DeriveInput, Error, Fields, Type, parse_macro_input, parse_quote};

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
/// its code is the discriminant, its name the enum's name.
#[proc_macro_derive(WireEnum)]
pub fn derive_wire_enum(input: TokenStream) -> TokenStream {
    let input = parse_macro_input!(input as DeriveInput);
    wire_enum(&input)
        .unwrap_or_else(Error::into_compile_error)
        .into()
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
    for variant in &data.variants {
        if !matches!(variant.fields, Fields::Unit) {
            return Err(Error::new_spanned(
                &variant.ident,
                "`#[derive(WireEnum)]` requires unit variants: a code carries no data",
            ));
        }
        variants.push(&variant.ident);
    }
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
    })
}
