"""The live station view (Textual): `trackside station`."""
