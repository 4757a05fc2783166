//! bake db.
