//! ROS 2 bag storage files in SQLite (`.db3`, Humble's default): the `topics` table, and the
//! `messages` of one topic read a few at a time by (timestamp, id), so that memory holds a
//! page of messages, not the file. Feature `db3`.

use super::{Encoding, RawMessage, Topic};
use rusqlite::{Connection, OpenFlags};
use std::path::Path;

/// Messages fetched from SQLite per query.
const PAGE: i64 = 8;

fn connect(path: &Path) -> Result<Connection, String> {
    Connection::open_with_flags(
        path,
        OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX,
    )
    .map_err(|e| format!("{}: {e}", path.display()))
}

/// The topics of one `.db3` file, with their types and message counts.
pub fn topics(path: &Path) -> Result<Vec<Topic>, String> {
    let db = connect(path)?;
    let mut q = db
        .prepare(
            "SELECT t.name, t.type, (SELECT COUNT(*) FROM messages m WHERE m.topic_id = t.id) \
             FROM topics t ORDER BY t.id",
        )
        .map_err(|e| format!("{}: not a ROS 2 bag file: {e}", path.display()))?;
    let rows = q
        .query_map([], |r| {
            Ok(Topic {
                name: r.get(0)?,
                type_name: r.get(1)?,
                messages: r.get::<_, i64>(2)? as u64,
            })
        })
        .and_then(|rows| rows.collect::<Result<Vec<_>, _>>());
    rows.map_err(|e| format!("{}: {e}", path.display()))
}

/// The messages of `topic` in one `.db3` file, by time.
pub struct Db3Messages {
    db: Connection,
    topic_id: Option<i64>,
    encoding: Encoding,
    /// The last message read: (timestamp, id).
    after: (i64, i64),
    page: std::vec::IntoIter<(i64, i64, Vec<u8>)>,
    done: bool,
}

impl Db3Messages {
    /// Opens `path` for `topic`'s messages (none if the file lacks the topic).
    pub fn new(path: &Path, topic: &str) -> Result<Self, String> {
        let db = connect(path)?;
        let found = db.query_row(
            "SELECT id, serialization_format FROM topics WHERE name = ?1",
            [topic],
            |r| Ok((r.get::<_, i64>(0)?, r.get::<_, String>(1)?)),
        );
        let (topic_id, format) = match found {
            Ok((id, f)) => (Some(id), f),
            Err(rusqlite::Error::QueryReturnedNoRows) => (None, "cdr".into()),
            Err(e) => return Err(format!("{}: {e}", path.display())),
        };
        let encoding = match format.as_str() {
            "cdr" => Encoding::Cdr,
            "ros1" => Encoding::Ros1,
            other => {
                return Err(format!(
                    "serialization format {other:?} is neither cdr nor ros1"
                ))
            }
        };
        Ok(Db3Messages {
            db,
            topic_id,
            encoding,
            after: (i64::MIN, i64::MIN),
            page: Vec::new().into_iter(),
            done: topic_id.is_none(),
        })
    }

    fn fetch(&mut self) -> Result<(), String> {
        let mut q = self
            .db
            .prepare_cached(
                "SELECT timestamp, id, data FROM messages WHERE topic_id = ?1 \
                 AND (timestamp > ?2 OR (timestamp = ?2 AND id > ?3)) \
                 ORDER BY timestamp, id LIMIT ?4",
            )
            .map_err(|e| e.to_string())?;
        let rows = q
            .query_map((self.topic_id, self.after.0, self.after.1, PAGE), |r| {
                Ok((r.get(0)?, r.get(1)?, r.get(2)?))
            })
            .and_then(|rows| rows.collect::<Result<Vec<_>, _>>())
            .map_err(|e| e.to_string())?;
        self.done = (rows.len() as i64) < PAGE;
        self.page = rows.into_iter();
        Ok(())
    }
}

impl Iterator for Db3Messages {
    type Item = Result<RawMessage, String>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            if let Some((t, id, data)) = self.page.next() {
                self.after = (t, id);
                return Some(Ok(RawMessage {
                    start: 0,
                    data,
                    encoding: self.encoding,
                    log_time_ns: t.max(0) as u64,
                }));
            }
            if self.done {
                return None;
            }
            if let Err(e) = self.fetch() {
                self.done = true;
                return Some(Err(e));
            }
        }
    }
}
