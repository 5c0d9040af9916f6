"""Seed-stream constants of an export (a module of its own so every part can import them)."""

#: third SeedSequence word of a placement group's entropy: [seed, group, PLACEMENT_STREAM]
PLACEMENT_STREAM = 1
