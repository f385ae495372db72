//! harvest-supervisor
