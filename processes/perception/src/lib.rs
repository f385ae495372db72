//! harvest-perception
