"""Track management: from the filter's labelled posterior to the objects a user sees."""
