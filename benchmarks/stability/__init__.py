"""`admmkit bench stability`: where each rule converges and how it fails, on the paper's contact examples."""
