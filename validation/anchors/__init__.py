"""Comparison ("anchor") libraries run in their own interpreters (never imported by StrideLab's runtime)."""
