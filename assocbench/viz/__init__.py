"""Pictures for people: frames with truth and associations drawn on them."""
