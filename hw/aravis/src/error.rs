//! [`AravisError`]: what went wrong in the library or at the camera.

/// An Aravis failure.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AravisError {
    /// The shared library could not be opened.
    #[error(
        "{library} cannot be loaded ({detail}): GigE Vision cameras need Aravis 0.8 \
         (Debian/Ubuntu: apt-get install libaravis-0.8-0 aravis-tools)"
    )]
    NotInstalled {
        /// The library's file name.
        library: &'static str,
        /// The loader's message.
        detail: String,
    },
    /// The library lacks a function this crate calls (an Aravis other than 0.8).
    #[error("{library} has no `{symbol}` ({detail}): Aravis 0.8 is required")]
    MissingSymbol {
        /// The library's file name.
        library: &'static str,
        /// The function.
        symbol: &'static str,
        /// The loader's message.
        detail: String,
    },
    /// A call returned a `GError`.
    #[error("{call}: {message} (code {code})")]
    Call {
        /// The C function.
        call: &'static str,
        /// The error's code in its domain.
        code: i32,
        /// The error's message.
        message: String,
    },
    /// A call returned nothing where an object was due (no camera, no stream).
    #[error("{call} returned no object: {detail}")]
    NoObject {
        /// The C function.
        call: &'static str,
        /// What was asked for.
        detail: String,
    },
    /// A string for the library held a NUL byte.
    #[error("{what} {text:?} holds a NUL byte")]
    NulInString {
        /// What the string names.
        what: &'static str,
        /// The string.
        text: String,
    },
}
