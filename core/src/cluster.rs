//! Grid-hashed DBSCAN over one window's events.
