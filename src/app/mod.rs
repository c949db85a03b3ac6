//! The application layer both front ends call (the `dynid` command line and the Python
//! bindings), one file per command: the options as a front end got them (flags or keywords,
//! `*Args`) are checked once into a request, with one message per mistake that names the option
//! as that front end spells it ([`Front`]); the request opens the data ([`source`]: files, or
//! tables from memory) and runs the library; the result is typed (the identification outcome,
//! the payload estimate), for the CLI to write and Python to return. Long work reports through
//! [`crate::progress`]; nothing here prints.

pub mod convert;
pub mod identify;
pub mod options;
pub mod payload;
pub mod source;

mod error;

pub use error::{AppError, Front};
