//! Import of external measurement files (MAT v5, DaISy ASCII) into [`crate::recording::Recording`].
