//! Linear-algebra helpers shared by the estimators and controllers.
