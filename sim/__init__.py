"""The world and the application: scenario language, generators, data model, entry points."""
