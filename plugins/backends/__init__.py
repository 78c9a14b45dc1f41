"""LLM backend plugins."""
