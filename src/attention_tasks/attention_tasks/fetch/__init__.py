"""Fetch: a room of objects where only the words say which one to pick up."""
