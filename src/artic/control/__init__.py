"""Controllers that turn a reference into robot actions (Chapter 5 joint tracking; the
Chapter 6 and 7 controllers belong here too). Pure numpy: no simulator, no files."""
