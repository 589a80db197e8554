"""Plug-ins for admmkit: one subpackage per problem (qp, contact, obstacle, lasso)."""
