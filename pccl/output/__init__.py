"""The outputs: text, JSON, trace files, typed result views, plots, the HTML viewer."""
