"""What a scan's result becomes: message contents, markers, pictures."""
