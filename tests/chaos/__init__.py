"""The randomized fault suite (docs/chaos.md)."""
