//! physfit-render
