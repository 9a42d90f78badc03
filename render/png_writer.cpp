// Placeholder: the preview renderer is being written (issue 6).
