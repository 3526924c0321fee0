"""Reports: the paper's tables, charts and figures, the style confusion matrix, a learned style's report, and
figures of strokes and datasets, all written from evaluations, never typed."""
