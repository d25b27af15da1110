"""The GGIW-CPHD filter: mixture, prediction, partitions, the multi-object update, reduction."""
