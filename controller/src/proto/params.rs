//! Parameter ids (placeholder until the table lands).
