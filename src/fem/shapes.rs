//! Shape functions, their derivatives and Gauss rules per cell kind.
