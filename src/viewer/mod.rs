//! The interactive viewer (being written).
