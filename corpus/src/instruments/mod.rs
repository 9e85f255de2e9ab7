//! One module per instrument or file format the campaign contains.
//!
//! Simulation (what the instrument would measure) and serialisation (the bytes its software
//! writes) sit side by side per instrument; the serialisers follow formats.md exactly, since
//! the compiler's readers are written against the same document.

pub mod bouguet;
pub mod e57;
pub mod las;
pub mod navcam;
pub mod opencv;
pub mod ply;
pub mod riegl;
pub mod sfm;
pub mod vicon;
