"""The tools beside the command line: runs, replay, the browser explorer, the editor tools."""
