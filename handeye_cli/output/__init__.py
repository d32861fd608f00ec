"""Results out: the result document, its YAML/JSON text and atomic writes, and the HTML report."""
