"""Capture formats: one module per format, each with a reader (an iterator of ``Chunk``) and, where it
makes sense, a writer."""
