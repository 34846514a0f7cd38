//! ROS 2 bag storage files in SQLite (`.db3`, Humble's default): the `topics` table, and the
//! `messages` of one topic read a few at a time by (timestamp, id), so that memory holds a
//! page of messages, not the file. Feature `db3`.

use super::error::RecordingError::{self, Database, NotThisFormat, Unsupported};
use super::{Encoding, RawMessage, Topic};
use rusqlite::{Connection, OpenFlags};
use std::path::Path;

/// Messages fetched from SQLite per query.
const PAGE: i64 = 8;

/// Opens `path` read-only, writing nothing beside it where it can. A bag in SQLite's
/// write-ahead-log mode, opened as a plain reader, leaves `-wal` and `-shm` files beside it (a
/// read-only connection cannot remove them). So a file with no log beside it is opened as
/// immutable (SQLite's `immutable=1`: no locks, no side files). Where a log is there (a bag
/// being recorded, or one whose recorder stopped before folding the log into the file), the
/// file is opened as a reader of the log too, or the messages only the log holds would be
/// missed.
fn connect(path: &Path) -> Result<Connection, RecordingError> {
    let has_log = std::fs::metadata(beside(path, "-wal")).is_ok_and(|m| m.len() > 0);
    let flags = OpenFlags::SQLITE_OPEN_READ_ONLY | OpenFlags::SQLITE_OPEN_NO_MUTEX;
    let opened = if has_log {
        Connection::open_with_flags(path, flags)
    } else {
        Connection::open_with_flags(immutable_uri(path), flags | OpenFlags::SQLITE_OPEN_URI)
    };
    opened.map_err(|e| Database(format!("{}: {e}", path.display())))
}

/// The file SQLite keeps beside `path` with `suffix` added to its name (`-wal`, `-shm`).
fn beside(path: &Path, suffix: &str) -> std::path::PathBuf {
    let mut p = path.as_os_str().to_owned();
    p.push(suffix);
    p.into()
}

/// `path` as an SQLite URI opening it immutable: `file:` and the path's bytes, every one but
/// letters, digits and `/-._~` percent-encoded (so that `?`, `#` and `%` in a name stay
/// part of it).
fn immutable_uri(path: &Path) -> String {
    let mut uri = String::from("file:");
    for &b in path.as_os_str().as_encoded_bytes() {
        if b.is_ascii_alphanumeric() || b"/-._~".contains(&b) {
            uri.push(char::from(b));
        } else {
            uri.push_str(&format!("%{b:02X}"));
        }
    }
    uri.push_str("?immutable=1");
    uri
}

/// The topics of one `.db3` file, with their types and message counts.
pub fn topics(path: &Path) -> Result<Vec<Topic>, RecordingError> {
    let db = connect(path)?;
    let mut q = db
        .prepare(
            "SELECT t.name, t.type, (SELECT COUNT(*) FROM messages m WHERE m.topic_id = t.id) \
             FROM topics t ORDER BY t.id",
        )
        .map_err(|e| NotThisFormat(format!("{}: not a ROS 2 bag file: {e}", path.display())))?;
    let rows = q
        .query_map([], |r| {
            Ok(Topic {
                name: r.get(0)?,
                type_name: r.get(1)?,
                messages: r.get::<_, i64>(2)? as u64,
            })
        })
        .and_then(|rows| rows.collect::<Result<Vec<_>, _>>());
    rows.map_err(|e| Database(format!("{}: {e}", path.display())))
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
    pub fn new(path: &Path, topic: &str) -> Result<Self, RecordingError> {
        let db = connect(path)?;
        let found = db.query_row(
            "SELECT id, serialization_format FROM topics WHERE name = ?1",
            [topic],
            |r| Ok((r.get::<_, i64>(0)?, r.get::<_, String>(1)?)),
        );
        let (topic_id, format) = match found {
            Ok((id, f)) => (Some(id), f),
            Err(rusqlite::Error::QueryReturnedNoRows) => (None, "cdr".into()),
            Err(e) => return Err(Database(format!("{}: {e}", path.display()))),
        };
        let encoding = match format.as_str() {
            "cdr" => Encoding::Cdr,
            "ros1" => Encoding::Ros1,
            other => {
                return Err(Unsupported(format!(
                    "serialization format {other:?} is neither cdr nor ros1"
                )))
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

    fn fetch(&mut self) -> Result<(), RecordingError> {
        let mut q = self.db.prepare_cached(
            "SELECT timestamp, id, data FROM messages WHERE topic_id = ?1 \
                 AND (timestamp > ?2 OR (timestamp = ?2 AND id > ?3)) \
                 ORDER BY timestamp, id LIMIT ?4",
        )?;
        let rows = q
            .query_map((self.topic_id, self.after.0, self.after.1, PAGE), |r| {
                Ok((r.get(0)?, r.get(1)?, r.get(2)?))
            })
            .and_then(|rows| rows.collect::<Result<Vec<_>, _>>())?;
        self.done = (rows.len() as i64) < PAGE;
        self.page = rows.into_iter();
        Ok(())
    }
}

impl Iterator for Db3Messages {
    type Item = Result<RawMessage, RecordingError>;

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

#[cfg(test)]
mod tests {
    use super::*;

    /// A bag of one topic with `messages` messages, rosbag2's tables, in write-ahead-log mode.
    fn wal_bag(path: &Path, messages: i64) -> Connection {
        let db = Connection::open(path).unwrap();
        db.pragma_update(None, "journal_mode", "WAL").unwrap();
        db.execute_batch(
            "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, \
             serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL); \
             CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, \
             timestamp INTEGER NOT NULL, data BLOB NOT NULL); \
             INSERT INTO topics VALUES (1, '/points', 'sensor_msgs/msg/PointCloud2', 'cdr', '');",
        )
        .unwrap();
        for i in 0..messages {
            db.execute("INSERT INTO messages VALUES (?1, 1, ?1, x'00')", [i + 1])
                .unwrap();
        }
        db
    }

    #[test]
    fn a_bag_in_wal_mode_is_read_without_files_left_beside_it_and_a_log_is_read_too() {
        let dir = crate::test_support::scratch_dir("db3-wal");
        // A name SQLite's URIs would otherwise cut: `?`, `#`, `%`, a space and UTF-8.
        let path = dir.join("run ?#%1 ü.db3");
        drop(wal_bag(&path, 3));
        let sides = || ["-wal", "-shm"].map(|s| beside(&path, s).exists());
        assert_eq!(
            sides(),
            [false, false],
            "the recorder's close folds its log in"
        );
        let listed = topics(&path).unwrap();
        assert_eq!((listed.len(), listed[0].messages), (1, 3));
        assert_eq!(Db3Messages::new(&path, "/points").unwrap().count(), 3);
        assert_eq!(sides(), [false, false], "reading left files beside the bag");

        // A recorder still writing: its log holds two messages more, not yet in the file.
        let recorder = Connection::open(&path).unwrap();
        recorder
            .pragma_update(None, "wal_autocheckpoint", 0)
            .unwrap();
        for i in 4..=5 {
            recorder
                .execute("INSERT INTO messages VALUES (?1, 1, ?1, x'00')", [i])
                .unwrap();
        }
        assert_eq!(topics(&path).unwrap()[0].messages, 5);
        assert_eq!(Db3Messages::new(&path, "/points").unwrap().count(), 5);
    }

    #[test]
    fn uris_keep_every_byte_of_the_name() {
        assert_eq!(
            immutable_uri(Path::new("/a b/c?d#e%f-g_h.i~j/ü")),
            "file:/a%20b/c%3Fd%23e%25f-g_h.i~j/%C3%BC?immutable=1"
        );
        assert_eq!(
            immutable_uri(Path::new("rel/x.db3")),
            "file:rel/x.db3?immutable=1"
        );
    }
}
