//! Finds the asymmetric circle grid among one window's centres.
